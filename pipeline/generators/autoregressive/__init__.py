"""The paper's affect-based autoregressive network: network and losses, training, fitting the variants, rollout, the
family."""

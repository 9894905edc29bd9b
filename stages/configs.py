"""The library's configs built from params.yaml sections, for the stages that need them (the library never
reads params itself)."""

from __future__ import annotations

from typing import Any

from pipeline.annotate.annotation import AnnotateConfig
from pipeline.generators.autoregressive.rollout import PlacementConfig
from pipeline.ingest.run import IngestConfig
from pipeline.ops.contacts import ContactConfig
from stages.common import mocap_root


def contact_config(params: dict[str, Any]) -> ContactConfig:
    return ContactConfig(**{k: float(v) for k, v in params["annotate"]["contacts"].items()})


def annotate_config(params: dict[str, Any]) -> AnnotateConfig:
    return AnnotateConfig(fps=float(params["ingest"]["target_fps"]), contacts=contact_config(params),
                          lowpass_seconds=float(params["annotate"]["lowpass_seconds"]))


def placement_config(params: dict[str, Any]) -> PlacementConfig:
    return PlacementConfig.from_dict(params.get("generate") or {}, params["ingest"]["target_fps"])


def ingest_config(params: dict[str, Any]) -> IngestConfig:
    p = params["ingest"]
    return IngestConfig(mocap_root=mocap_root(params), target_fps=float(p["target_fps"]), window=int(p["window"]),
                        stride=int(p["stride"]), min_gait_speed=float(p["min_gait_speed"]),
                        chunk_frames=int(p["chunk_frames"]))

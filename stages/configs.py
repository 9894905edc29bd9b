"""The library's configs built from params.yaml sections, for the stages, tests and benchmarks that need them (the
library never reads params itself). Each builder imports its own config class, so a stage that imports this module
loads (and depends on) only the library it uses."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from stages.common import mocap_root

if TYPE_CHECKING:
    from pipeline.annotate.annotation import AnnotateConfig
    from pipeline.annotate.contact_validation import ValidationConfig
    from pipeline.generators.autoregressive.rollout import PlacementConfig
    from pipeline.generators.motion_graph.family import WalkConfig
    from pipeline.generators.motion_graph.search import SearchConfig
    from pipeline.generators.pca_gaussian.synthesis import WalkSettings
    from pipeline.ingest.run import IngestConfig
    from pipeline.ops.contacts import ContactConfig


def contact_config(params: dict[str, Any]) -> ContactConfig:
    from pipeline.ops.contacts import ContactConfig

    return ContactConfig(**{k: float(v) for k, v in params["annotate"]["contacts"].items()})


def annotate_config(params: dict[str, Any]) -> AnnotateConfig:
    from pipeline.annotate.annotation import AnnotateConfig

    return AnnotateConfig(fps=float(params["ingest"]["target_fps"]), contacts=contact_config(params),
                          lowpass_seconds=float(params["annotate"]["lowpass_seconds"]))


def placement_config(params: dict[str, Any]) -> PlacementConfig:
    from pipeline.generators.autoregressive.rollout import PlacementConfig

    return PlacementConfig.from_dict(params.get("generate") or {}, params["ingest"]["target_fps"],
                                     contact_config(params))


def walk_settings(params: dict[str, Any]) -> WalkSettings:
    from pipeline.generators.pca_gaussian.synthesis import WalkSettings

    return WalkSettings.from_dict((params.get("pca_gaussian") or {}).get("synthesis"))


def ingest_config(params: dict[str, Any]) -> IngestConfig:
    from pipeline.ingest.run import IngestConfig
    from pipeline.ops.floor import FloorConfig

    p = params["ingest"]
    return IngestConfig(mocap_root=mocap_root(params), target_fps=float(p["target_fps"]), window=int(p["window"]),
                        stride=int(p["stride"]), min_gait_speed=float(p["min_gait_speed"]),
                        chunk_frames=int(p["chunk_frames"]),
                        max_joint_speed=float(p.get("max_joint_speed", IngestConfig.max_joint_speed)),
                        floor=FloorConfig.from_dict(p.get("floor")))


def validation_config(params: dict[str, Any]) -> ValidationConfig:
    from pipeline.annotate.contact_validation import ValidationConfig

    return ValidationConfig(**{k: float(v) for k, v in (params.get("validate_contacts") or {}).items()})


def motion_graph_settings(params: dict[str, Any], **search: Any) -> tuple[SearchConfig, WalkConfig]:
    """The motion graph family's search and walk settings (``motion_graph.search``, ``.walk``); ``search``
    overrides (e.g. ``emotion=False`` for the ablation)."""
    import dataclasses

    from pipeline.generators.motion_graph.family import WalkConfig
    from pipeline.generators.motion_graph.search import SearchConfig

    p = params.get("motion_graph") or {}
    return (dataclasses.replace(SearchConfig.from_dict(p.get("search")), **search),
            WalkConfig.from_dict(p.get("walk")))

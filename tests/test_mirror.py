"""Left-right mirroring (pipeline/ops/mirror.py): the mirror of a mirror is the gait; forward kinematics of the
mirrored rotations gives the mirrored positions; the annotation code run on a mirrored gait finds the mirrored
contacts, phase and features. On random poses of the canonical skeleton (no data needed) and on the reference
clips' real gaits (``reference_annotated``: every window of three real clips, fast tier)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from pipeline.annotate.annotation import annotate_windows
from pipeline.ops.contacts import CONTACT_POINTS, stepping_phase
from pipeline.ops.features import AFFECTIVE_FEATURES, affective_features, movement_features
from pipeline.ops.kinematics import canonical_positions
from pipeline.ops.mirror import (
    affective_counterparts,
    check_mirror_symmetric,
    counterparts,
    mirror_contacts,
    mirror_gait,
    mirror_phase,
    mirror_positions,
    mirror_rotations,
    mirror_side_name,
)
from stages.common import load_params
from stages.configs import annotate_config

ARRAYS = ("positions", "rotations", "root_path", "heading", "contacts", "phase", "phase_rate", "affective", "movement")
# The paper's 18 features that measure one side of the body, in mirror pairs (by definition, joints swapped):
# 2/3 hand tip to neck over hand tip to pelvis, 7/8 elbows, 9/10 head-neck-shoulder, 11/12 head-pelvis-knee,
# 15/16 knees. The other 8 (0, 1, 4, 5, 6, 13, 14, 17) span both sides symmetrically and are their own mirror.
MIRROR_PAIRS = {2: 3, 7: 8, 9: 10, 11: 12, 15: 16}


def circular_difference(a, b) -> np.ndarray:
    """|a - b| on the circle, radians."""
    d = np.remainder(np.asarray(a, np.float64) - np.asarray(b, np.float64), 2 * math.pi)
    return np.minimum(d, 2 * math.pi - d)


def random_pose(skeleton, shape=(3, 8), seed=0) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    q = torch.randn(*shape, skeleton.joint_count, 4, generator=g, dtype=torch.float64)
    return torch.randn(*shape, 3, generator=g, dtype=torch.float64), q / q.norm(dim=-1, keepdim=True)


def test_counterparts_are_found_by_name_and_the_skeleton_is_its_own_mirror(skeleton):
    sigma = counterparts(skeleton.names)
    names = skeleton.names
    assert all(names[sigma[j]] == n.replace("left", "#").replace("right", "left").replace("#", "right")
               for j, n in enumerate(names))
    assert [sigma[s] for s in sigma] == list(range(len(names)))
    assert sigma[skeleton.index("root")] == skeleton.index("root")
    assert sigma[skeleton.index("left_hand_index")] == skeleton.index("right_hand_index")
    check_mirror_symmetric(skeleton)
    assert mirror_side_name("walk-turn-left") == "walk-turn-right" and mirror_side_name("leftover") == "leftover"
    assert counterparts(CONTACT_POINTS) == (2, 3, 0, 1)


def test_an_asymmetric_skeleton_is_refused(skeleton):
    import dataclasses
    offsets = skeleton.offsets.copy()
    offsets[skeleton.index("left_elbow"), 0] += 0.01
    with pytest.raises(ValueError, match="right_elbow"):
        check_mirror_symmetric(dataclasses.replace(skeleton, offsets=offsets))


def test_affective_features_pair_up_by_definition(skeleton):
    perm = affective_counterparts(counterparts(skeleton.names))
    expected = list(range(len(AFFECTIVE_FEATURES)))
    for a, b in MIRROR_PAIRS.items():
        expected[a], expected[b] = b, a
    assert list(perm) == expected


def test_forward_kinematics_of_mirrored_rotations_is_the_mirrored_pose(skeleton):
    root, q = random_pose(skeleton)
    offsets = torch.from_numpy(skeleton.offsets)
    sigma = counterparts(skeleton.names)
    positions = canonical_positions(root, q, offsets, skeleton.parents)
    mirrored = mirror_positions(positions, sigma)
    again = canonical_positions(mirrored[..., 0, :], mirror_rotations(q, sigma), offsets, skeleton.parents)
    assert (again - mirrored).abs().max() < 1e-12
    assert torch.equal(mirror_rotations(mirror_rotations(q, sigma), sigma), q)
    assert torch.equal(mirror_positions(mirrored, sigma), positions)
    # the features of the mirrored pose: the original's with the mirror pairs swapped
    perm = list(affective_counterparts(sigma))
    assert torch.allclose(affective_features(mirrored), affective_features(positions)[..., perm], atol=1e-10)


def test_phase_of_swapped_strikes_is_the_phase_shifted_by_pi():
    left, right = [5, 36, 68], [20, 52]
    theta = stepping_phase(90, left, right)
    swapped = stepping_phase(90, right, left)  # the mirrored gait's left strikes are the original's right strikes
    assert circular_difference(swapped, mirror_phase(theta)).max() < 1e-12
    assert circular_difference(mirror_phase(mirror_phase(theta)), theta).max() < 1e-12
    assert (mirror_phase(theta) >= 0).all() and (mirror_phase(theta) < 2 * math.pi).all()


@pytest.fixture(scope="module")
def real_gaits(reference_annotated):
    table, arrays = reference_annotated
    return table, {name: torch.from_numpy(arrays[name]) for name in ARRAYS}


@pytest.fixture(scope="module")
def mirrored(real_gaits, skeleton):
    return mirror_gait(real_gaits[1], skeleton)


def test_a_mirrored_real_gait_mirrored_again_is_the_gait(real_gaits, mirrored, skeleton):
    gait = real_gaits[1]
    back = mirror_gait(mirrored, skeleton)
    for name in ARRAYS:
        if name == "phase":  # θ + π + π wraps through float32 rounding
            assert circular_difference(back[name], gait[name]).max() < 1e-6
        else:
            assert torch.equal(back[name], gait[name]), name
    assert not torch.equal(mirrored["positions"], gait["positions"])


def test_forward_kinematics_reproduces_mirrored_real_positions(real_gaits, mirrored, skeleton):
    offsets = torch.from_numpy(skeleton.offsets)

    def fk_error(g):
        pos = g["positions"].double()
        fk = canonical_positions(pos[..., 0, :], g["rotations"].double(), offsets, skeleton.parents)
        return torch.linalg.vector_norm(fk - pos, dim=-1).max().item()

    assert fk_error(mirrored) < 1e-4
    assert fk_error(mirrored) == pytest.approx(fk_error(real_gaits[1]), abs=1e-6)  # mirroring adds no error


def test_annotation_of_a_mirrored_real_gait_is_the_mirrored_annotation(real_gaits, mirrored, skeleton):
    """Contacts swap sides exactly; the phase is the original's + π (compared on the circle; float32 storage
    only, no frame of difference is needed: contacts are decided from speeds and heights, which mirroring keeps
    bit for bit); the affective features are the original's with the mirror pairs swapped; the movement
    features are unchanged (heading-to-path angle and curvature are unsigned)."""
    table, gait = real_gaits
    ann, clips = annotate_windows(table.column("clip_id").to_pylist(), table.column("t_start").to_numpy(),
                                  mirrored["positions"].numpy(), mirrored["rotations"].numpy(), skeleton,
                                  annotate_config(load_params()))
    assert len(clips) == 3 and all(c["phase_defined"] for c in clips.values())
    assert np.array_equal(ann["contacts"], mirror_contacts(gait["contacts"]).numpy())
    assert np.array_equal(ann["contacts"][..., [2, 3, 0, 1]], gait["contacts"].numpy())
    assert circular_difference(ann["phase"], mirrored["phase"]).max() < 1e-5
    assert circular_difference(ann["phase"], gait["phase"].numpy() + math.pi).max() < 1e-5
    assert np.abs(ann["phase_rate"] - gait["phase_rate"].numpy()).max() < 1e-5
    assert np.abs(ann["affective"] - mirrored["affective"].numpy()).max() < 1e-4
    pairs = [*MIRROR_PAIRS.items(), *((b, a) for a, b in MIRROR_PAIRS.items())]
    for a, b in pairs:
        assert np.abs(ann["affective"][..., a] - gait["affective"][..., b].numpy()).max() < 1e-4
    assert np.abs(ann["movement"] - gait["movement"].numpy()).max() < 1e-5
    # the stored movement features recomputed from the mirrored positions directly
    recomputed = movement_features(mirrored["positions"].double(), annotate_config(load_params()).lowpass_frames)
    assert torch.allclose(recomputed.float(), gait["movement"], atol=1e-5)


def test_mirrored_heading_and_root_path_follow_the_mirrored_pose(mirrored):
    from pipeline.ops.geometry import heading_angle
    root_rotation = mirrored["rotations"][..., 0, :].double()
    assert circular_difference(heading_angle(root_rotation), mirrored["heading"]).max() < 1e-5
    assert torch.equal(mirrored["root_path"], mirrored["positions"][..., 0, :][..., [0, 2]])


def test_a_column_without_a_rule_is_refused(real_gaits, skeleton):
    with pytest.raises(KeyError, match="plan_seed"):
        mirror_gait({**real_gaits[1], "plan_seed": torch.zeros(1)}, skeleton)

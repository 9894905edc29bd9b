"""Independent emotion recognisers: trained on real labelled train gaits only, used by the audit and the
evaluation to read which emotion a gait shows, and never inside a generator's training loss.

``RecognitionInputs`` is what they read (any number of frames >= 10), ``fit_recogniser`` fits one of
``RECOGNISERS``, and the scoring functions (confusion, scores, majority baseline, bootstrap intervals over clips)
score its answers.
"""

from pipeline.recognition.inputs import MIN_FRAMES, RecognitionInputs, heading_frame_poses, pose_channels
from pipeline.recognition.models import (
    RECOGNISER_NAMES,
    RECOGNISERS,
    Recogniser,
    RecogniserConfig,
    SummaryConfig,
    TemporalConfig,
    fit_recogniser,
    gait_summaries,
    summary_features,
)
from pipeline.recognition.scoring import (
    SCORES,
    bootstrap_delta_interval,
    bootstrap_interval,
    confusion,
    majority_baseline,
    scores,
)

__all__ = ["MIN_FRAMES", "RECOGNISERS", "RECOGNISER_NAMES", "SCORES", "RecognitionInputs", "Recogniser",
           "RecogniserConfig", "SummaryConfig", "TemporalConfig", "bootstrap_delta_interval", "bootstrap_interval",
           "confusion", "fit_recogniser", "gait_summaries", "heading_frame_poses", "majority_baseline",
           "pose_channels", "scores", "summary_features"]

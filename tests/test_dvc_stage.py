"""The real DVC pipeline in a fresh copy of the repository, and the stages' declared dependencies."""

import dataclasses
import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from stages.common import REPO
from tests.conftest import MOCAP

COPY = ["dvc.yaml", "params.yaml", "pipeline", "stages", "manifests", ".dvc/config", ".dvcignore"]
DVC = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]


def _run(args, cwd, env):
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, check=True)


@dataclasses.dataclass
class SmallRepro:
    """A fresh copy of the repository after one `dvc repro` of the real stages, sized to a test."""

    work: Path
    env: dict[str, str]
    params: dict
    stdout: str
    seconds: dict[str, float]  # per stage, from its "Running stage" line to the next one's

    def dvc(self, *args: str) -> subprocess.CompletedProcess:
        return _run([sys.executable, "-m", "dvc", *args], self.work, self.env)


@pytest.fixture(scope="module")
def small_repro(tmp_path_factory, mocap) -> SmallRepro:
    work = tmp_path_factory.mktemp("dvc") / "repo"
    for rel in COPY:
        src, dst = REPO / rel, work / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__")) if src.is_dir() else shutil.copy(src, dst)
    params = yaml.safe_load((work / "params.yaml").read_text())
    params["data"]["mocap_root"] = str(MOCAP)
    # The real stages, sized to a test: a few epochs, few agents (the full sizes are measured by `make repro`).
    params["train"].update(epochs=3, validate_every=3, progress_every=1, batch_size=32)
    params["train"]["model"].update(gru_hidden=32, versor_hidden=32)
    params["evaluate"].update(rollout_steps=50, rollout_agents=3, expressiveness_steps=20, transition_steps=20,
                              transition_agents=2)
    # The audit and the family comparison fit recognisers many times over (seeds x augmentations x families); here
    # a few fits, each short, since the kill test below runs every stage about three times more. The CNN cap is the
    # real-only fit's whole length today (207 labelled train gaits: 4 batches of 64 x 40 epochs), so only the
    # augmented fits are cut; should the labelled train split grow, the real-only fit is cut too, and the check that
    # real labels are learnable (check_audit) is what would say so.
    params["audit"].update(seeds={"summary_mlp": [0, 1], "temporal_cnn": [0]}, bootstrap_resamples=200)
    params["audit"]["recognisers"]["temporal"]["max_steps"] = 160
    params["evaluate_families"].update(sensitivity_rows=8, ablation_rows=24)
    (work / "params.yaml").write_text(yaml.safe_dump(params))
    env = dict(os.environ, DVC_NO_ANALYTICS="1", PATH=f"{Path(sys.executable).parent}:{os.environ['PATH']}")
    _run(["git", "init", "-q"], work, env)
    lines, started = [], {}
    with subprocess.Popen([sys.executable, "-m", "dvc", "repro"], cwd=work, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True) as proc:
        for line in proc.stdout:
            lines.append(line)
            if m := re.match(r"Running stage '(\w+)'", line):
                started[m.group(1)] = time.monotonic()
        ended = time.monotonic()
    stdout = "".join(lines)
    assert proc.returncode == 0, stdout[-3000:]
    order = sorted(started, key=started.get)
    seconds = {s: (started[n] if n else ended) - started[s] for s, n in zip(order, order[1:] + [None])}
    return SmallRepro(work, env, params, stdout, seconds)


@pytest.mark.slow
def test_dvc_repro_runs_every_stage_then_is_a_noop(small_repro, tmp_path):
    work, params, dvc = small_repro.work, small_repro.params, small_repro.dvc
    for stage in DVC:
        assert f"Running stage '{stage}'" in small_repro.stdout
    report = json.loads((work / "reports/ingest.json").read_text())
    assert report["files_seen"] >= 361 and report["gaits"] > 1000
    split = json.loads((work / "reports/split.json").read_text())
    assert split["clips_in_two_splits"] == [] and split["totals"]["test"]["gaits"] > 0
    assert json.loads((work / "reports/contacts.json").read_text())["acceptance"]["passed"]
    trained = json.loads((work / "reports/train.json").read_text())
    variants = set(params["train"]["variants"])
    assert {"full", "no_affect"} <= variants and set(trained["variants"]) == variants
    for name, v in trained["variants"].items():
        assert hashlib.sha256((work / v["checkpoint"]).read_bytes()).hexdigest() == v["sha256"]
    evaluation = json.loads((work / "reports/eval.json").read_text())
    assert evaluation["split"] == "test" and evaluation["table1_gaits"] == split["totals"]["test"]["gaits"]
    assert set(evaluation["table1"]) == {"zero_velocity", "constant_velocity"} | variants
    assert (work / "reports/eval.md").read_text().startswith("# Generator evaluation")
    published = work / "data/published/synthesized_emotive_gaits"
    check_published(published, work)
    check_audit(work / "reports/audit", published, tmp_path, work / "params.yaml")
    before = _digests(published)
    # Rerun what makes the published files: every byte the same, provenance.json and SHA256SUMS included (they
    # carry the md5 of every stage output in dvc.lock, so no output may hold a timing).
    for stage in ("train", "synthesize", "fit_pca_gaussian", "synthesize_pca_gaussian", "fit_motion_graph",
                  "synthesize_motion_graph", "publish"):
        dvc("repro", "-f", "-s", stage)
    assert _digests(published) == before
    assert "up to date" in dvc("status").stdout
    second = dvc("repro")
    assert "Running stage" not in second.stdout and "didn't change" in second.stdout


def _stage_outputs(work: Path, stage: str) -> dict[str, str]:
    """sha256 of every file a stage declares (outs, metrics, plots; directories walked), by path."""
    out = {}
    for entry in (e for key in ("outs", "metrics", "plots") for e in DVC[stage].get(key, [])):
        path = work / (entry if isinstance(entry, str) else next(iter(entry)))
        files = sorted(f for f in path.rglob("*") if f.is_file()) if path.is_dir() else [path] if path.exists() else []
        out.update({str(f.relative_to(work)): hashlib.sha256(f.read_bytes()).hexdigest() for f in files})
    return out


@pytest.mark.slow
def test_a_stage_killed_mid_run_leaves_no_output_that_is_accepted_and_reruns_byte_identical(small_repro):
    """Every stage, SIGKILLed (DVC and the stage's Python together) at 30 % and 70 % of its run: each file it
    declares is then either missing or complete (atomic writes: the same bytes as a whole run's), never a partial
    file under the final name; whatever is left that differs, DVC does not accept (the stage is not up to date) and
    reruns it; the rerun writes the same bytes, and no temporary file stays anywhere in the repository."""
    work, dvc = small_repro.work, small_repro.dvc
    reference = {stage: _stage_outputs(work, stage) for stage in DVC}
    everything = _all_files(work)
    for stage in DVC:
        for fraction in (0.3, 0.7):
            proc = subprocess.Popen([sys.executable, "-m", "dvc", "repro", "-f", "-s", stage], cwd=work,
                                    env=small_repro.env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                    start_new_session=True)
            try:
                proc.wait(timeout=fraction * small_repro.seconds[stage])
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            left = _stage_outputs(work, stage)
            # a file under its final name is whole (atomic writes); a temporary file inside a directory output may
            # be left, but then the directory is not what dvc.lock says and DVC must not accept it
            partial = {f for f, digest in left.items() if reference[stage].get(f) != digest}
            assert all(Path(f).name.startswith(".") for f in partial), (
                f"{stage} killed at {fraction:.0%}: partial files under their final names {sorted(partial)}")
            status = dvc("status", stage).stdout
            if left != reference[stage]:
                assert "changed outs" in status or "modified" in status or "deleted" in status, (stage, status)
            dvc("repro", "-s", stage)
            assert _stage_outputs(work, stage) == reference[stage], f"{stage}: the rerun after a kill differs"
            assert "up to date" in dvc("status").stdout
            stray = _all_files(work) - everything
            assert not stray, f"{stage} killed at {fraction:.0%} left files behind: {sorted(stray)[:10]}"


def _all_files(work: Path) -> set[str]:
    """Every file of the copy outside DVC's and git's own folders (their caches and locks are theirs to keep)."""
    return {str(f.relative_to(work)) for f in work.rglob("*")
            if f.is_file() and f.relative_to(work).parts[0] not in (".dvc", ".git")}


def _digests(directory: Path) -> dict[str, str]:
    return {str(f.relative_to(directory)): hashlib.sha256(f.read_bytes()).hexdigest()
            for f in sorted(directory.rglob("*")) if f.is_file()}


def check_published(published: Path, work: Path) -> None:
    """The published directory as a user meets it: every reader, the loader's verify, Croissant, checksums."""
    import duckdb
    import h5py
    import numpy as np
    import pyarrow.dataset as pds

    from pipeline.dataset import GaitDataset, load_dataframe, verify

    assert verify(published) == []
    subprocess.run(["sha256sum", "--quiet", "-c", "SHA256SUMS"], cwd=published, check=True)
    validate = subprocess.run([str(Path(sys.executable).parent / "mlcroissant"), "validate", "--jsonld",
                               str(published / "croissant.json")], capture_output=True, text=True)
    assert validate.returncode == 0, validate.stderr[-2000:]
    frame = load_dataframe(published)
    everything = frame[frame["kind"] == "synthetic"]
    families = {"autoregressive_affect": 5000, "pca_gaussian": 5000, "motion_graph": 5000}
    assert everything["generator"].value_counts().to_dict() == families
    assert (frame["kind"] == "real").sum() > 1000 and frame.loc[frame["kind"] == "real", "generator"].isna().all()
    for name, family in everything.groupby("generator"):
        emotions = np.stack(family["emotion"].to_numpy())
        assert emotions.shape == (5000, 4) and np.abs(emotions.sum(-1) - 1).max() <= 1e-5, name
        per_frame = np.stack(family["emotion_per_frame"].to_numpy())
        assert per_frame.shape == (5000, 60, 4) and np.abs(per_frame.sum(-1) - 1).max() <= 1e-5, name
        assert family[["checkpoint_sha256", "trajectory_id", "emotion_recipe"]].notna().all().all(), name
        assert family["checkpoint_sha256"].nunique() == 1, name
    # the same plan rows: family ids differ only by the family's name
    synthetic = everything[everything["generator"] == "autoregressive_affect"]
    other = everything[everything["generator"] == "pca_gaussian"]
    assert [g.replace("syn-pca_gaussian-", "syn-") for g in other["gait_id"]] == list(synthetic["gait_id"])
    assert other["seed_gait_id"].isna().all() and synthetic["seed_gait_id"].notna().all()
    graph = everything[everything["generator"] == "motion_graph"]
    assert [g.replace("syn-motion_graph-", "syn-") for g in graph["gait_id"]] == list(synthetic["gait_id"])
    # a motion-graph gait names the real frames it plays: 60 of them, of train-split clips
    assert graph["source_segments"].notna().all() and everything.loc[everything["generator"] != "motion_graph",
                                                                      "source_segments"].isna().all()
    train_clips = set(frame.loc[(frame["kind"] == "real") & (frame["split"] == "train"), "source_file"])
    for segments in graph["source_segments"].iloc[::500]:
        runs = json.loads(segments)
        assert sum(last - first + 1 for _, first, last in runs) == 60
    generators = json.loads((published / "generators.json").read_text())
    assert {k: v["gaits"] for k, v in generators.items()} == families
    assert "source_segments" in generators["motion_graph"]["lineage"] and train_clips
    cycles = generators["pca_gaussian"]["model_lineage"]["cycles_per_emotion_model"]
    assert all(cycles[e] for e in ("happy", "sad", "angry", "neutral"))
    check_hugging_face(published, frame, work / "hf_cache")
    real = frame[frame["kind"] == "real"]
    assert real[["source_file", "source_sha256", "t_start", "t_end"]].notna().all().all()
    assert set(real.loc[real["gait_id"].isin(synthetic["gait_id"]), "gait_id"]) == set()
    # seeds: labelled train-split walks (the held-out clips stay unseen by the generator)
    seeds = real.set_index("gait_id").loc[sorted(set(synthetic["seed_gait_id"]))]
    assert (seeds["split"] == "train").all() and seeds["label_method"].notna().all()
    # what the card and the Croissant record say of the seeds and the contents is what the files hold
    card = " ".join((published / "README.md").read_text().split())
    assert f"frames of a labelled real train-split gait ({', '.join(sorted(set(seeds['content'])))})" in card
    collection = " ".join(json.loads((published / "croissant.json").read_text())["rai:dataCollection"].split())
    assert "the seeded ones (autoregressive_affect) continue the first frames of labelled real train-split" in collection
    labelled = real[real["label_method"].notna()]
    for content, n in labelled["content"].value_counts().items():
        assert f"| real labelled, {content} | {n} |" in card, content
    for name in families:
        assert f"| `{name}` | 5000 |" in card, name
    publish_report = json.loads((work / "reports/publish.json").read_text())["limitations"]
    assert set(publish_report["trunk_turn_deg"]) == {"real_train_walks", *families}
    table = pds.dataset(sorted(published.glob("gaits-*.parquet")), format="parquet").to_table()
    assert table.num_rows == len(frame)
    positions = table["positions"].combine_chunks().flatten().to_numpy().reshape(-1, 60, 21, 3)
    assert np.array_equal(positions[0], np.asarray(frame["positions"].iloc[0]))
    (count,), = duckdb.sql(f"select count(*) from read_parquet('{published}/gaits-*.parquet') "
                           "where kind = 'synthetic'").fetchall()
    assert count == 15000
    with h5py.File(published / "gaits.h5") as h5:
        assert h5["positions"].shape == (len(frame), 60, 21, 3) and h5["rotations"].shape == (len(frame), 60, 21, 4)
        assert h5["emotion_per_frame"].shape == (len(frame), 60, 4)
        assert list(h5.attrs["emotion_order"]) == ["happy", "sad", "angry", "neutral"]
    item = GaitDataset(published)[len(frame) - 1]
    assert tuple(item["positions"].shape) == (60, 21, 3)
    # BVH export of a real and a synthetic gait, read back by our own reader: the same positions (< 1 mm)
    from pipeline.io.bvh_writer import bvh_file_name
    from pipeline.core.skeleton import load_skeleton
    from stages.cli import main as emogait
    from stages.common import SKELETON
    from tests.test_bvh_export import TOLERANCE_M, _bvh_positions

    chosen = [real["gait_id"].iloc[0], synthetic["gait_id"].iloc[-1]]
    assert emogait(["export-bvh", *chosen, "--dataset", str(published), "--out", str(work / "bvh")]) == 0
    for gait_id in chosen:
        read_back = _bvh_positions(work / "bvh" / bvh_file_name(gait_id), load_skeleton(SKELETON)).numpy()
        stored = frame.loc[frame["gait_id"] == gait_id, "positions"].iloc[0]
        assert np.linalg.norm(read_back - stored, axis=-1).max() < TOLERANCE_M, gait_id
    for stage in ("synthesize", "synthesize_pca_gaussian", "synthesize_motion_graph"):
        report = json.loads((work / f"reports/{stage}.json").read_text())
        assert report["gaits"] == 5000 and report["finite"], stage
        # the motion graph's frames are real frames, blended only near its transitions: copies by design
        if stage == "synthesize_motion_graph":
            assert report["real_frames_by_design"]["share"] > 0.5 and report["search"]["gaits"] == 5000
        else:
            assert report["copied_real_frames"] == 0, stage
        assert report["emotion_novelty"]["passed"] and report["trajectory_novelty"]["passed"], stage
        assert set(report["walking"]["synthetic"]) == {"happy", "sad", "angry", "neutral"}, stage
    previews = {p.name for p in (published / "previews").glob("*.png")}
    assert {"emotions.png", "transition.png", "emotions_pca_gaussian.png", "transition_pca_gaussian.png",
            "emotions_motion_graph.png", "transition_motion_graph.png"} <= previews


def check_hugging_face(published: Path, frame, cache: Path) -> None:
    """The card's Hugging Face configs, loaded by ``datasets`` as a user would (offline, a scratch cache): each
    part's gaits, and positions reshaped to (60, 21, 3) as the card documents."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")  # local files only: nothing may reach the Hub
    os.environ.setdefault("HF_DATASETS_OFFLINE", "1")
    import datasets
    import numpy as np

    card = (published / "README.md").read_text()
    assert card.startswith("---\n")
    header = yaml.safe_load(card.split("---\n")[1])
    configs = {c["config_name"]: c for c in header["configs"]}
    assert set(configs) == {"autoregressive_affect", "pca_gaussian", "motion_graph", "real", "all"}
    assert configs["autoregressive_affect"].get("default") is True
    for name, expected in (("motion_graph", 5000), ("real", int((frame["kind"] == "real").sum()))):
        files = sorted(published.glob(configs[name]["data_files"][0]["path"]))
        ds = datasets.load_dataset("parquet", data_files=[str(f) for f in files], split="train",
                                   cache_dir=str(cache))
        assert ds.num_rows == expected, name
        positions = ds.with_format("numpy", columns=["positions"])[:]["positions"].reshape(-1, 60, 21, 3)
        first = frame.loc[frame["gait_id"] == ds[0]["gait_id"], "positions"].iloc[0]
        assert positions.shape == (expected, 60, 21, 3) and np.array_equal(positions[0], first), name


def check_audit(reports: Path, published: Path, tmp_path: Path, params: Path) -> None:
    """The audit stage's report, and `emogait audit` (with the run's ``params``) on a copy of the published
    directory moved elsewhere: the same figures."""
    from stages.cli import main as emogait

    metrics = json.loads((reports / "metrics.json").read_text())
    assert metrics["problem_count"] == 0 and metrics["kinds"]["synthetic"] == 15000
    recognition = metrics["recognisability"]
    assert set(recognition["by_recogniser"]) == {"summary_mlp", "temporal_cnn"}
    for kind, figures in recognition["by_recogniser"].items():
        held_out = figures["real_held_out"]
        assert held_out["accuracy_mean"] > recognition["chance_accuracy"] + 0.25, kind  # real labels are learnable
        assert set(figures["augmentation_delta"]) == {"accuracy", "balanced_accuracy", "macro_f1"}
        assert set(held_out["majority_baseline"]) == {"class", "accuracy", "balanced_accuracy", "macro_f1"}
    page = (reports / "index.html").read_text()
    assert page.count("data:image/png;base64,") == len(list(reports.glob("*.png"))) == 7
    moved = tmp_path / "downloads" / "someone_elses_copy"
    shutil.copytree(published, moved)
    assert emogait(["audit", str(moved), "--out", str(tmp_path / "their_audit"), "--params", str(params)]) == 0
    theirs = json.loads((tmp_path / "their_audit" / "metrics.json").read_text())
    assert theirs["labels"] == metrics["labels"] and theirs["recognisability"] == recognition


@pytest.mark.slow  # one Python (torch, dask, ...) per stage
@pytest.mark.parametrize("stage", sorted(DVC))
def test_stage_deps_cover_every_library_module_it_imports(stage):
    code = (f"import sys, stages.{stage}; print('\\n'.join(sorted(m.__file__ for n, m in sys.modules.items() "
            "if n.split('.')[0] in ('pipeline', 'stages') and getattr(m, '__file__', None))))")
    files = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True).stdout
    deps = [REPO / d for d in DVC[stage]["deps"] if not d.startswith("$")]
    for f in files.split():
        path = Path(f)
        if path.name == "__init__.py" or path.suffix == ".so":
            continue
        assert any(path == d or d in path.parents for d in deps), f"stage {stage}: {path.relative_to(REPO)} not in deps"

"""Fuzz benchmark: mutated real BVH and C3D files through the readers and the ingest screen.

Every input is a real seed file mutated by ``tests.fuzzing`` (bit flips, byte inserts and deletes, truncation,
duplicated / deleted lines, joint blocks, MOTION headers and parameter records, huge counts, NaN / Inf and very
long numbers, odd encodings, C3D header words and parameter framing), deterministically from ``--seed`` and the
input's index. Each goes through the per-file ingest (``pipeline.ingest.run.ingest_chunk``: the screen, the
format's reader, then the C3D marker screen or BVH retargeting), which promises to record bad input, never to
raise. Outcomes: ingested, filtered, quarantined (by the ingest), rejected_by_reader (the screen's "malformed
BVH/C3D" quarantine: BvhError or C3dError) and unexpected: any other exception escaping, a reader rejection it
cannot explain, parsed BVH frames that differ from Python's float() or the Arrow fallback, non-finite windows,
an input running over ``--timeout`` seconds, or a worker process dying (a crash in the C MOTION parser). Each
unexpected outcome has a stage: "screen" (raised in the screen or a reader: what the issue's acceptance counts)
or "ingest" (after the screen: retargeting, clip repair, windows). Unexpected inputs are listed with their index,
seed and mutations: ``--replay INDEX`` reruns one with its traceback. Besides the inputs, the C MOTION parser
alone gets ``PARSER_CASES`` token soups per input, checked against its contract (``motion_parser``).

Memory: each worker runs under RLIMIT_DATA = its footprint after start-up + ``--headroom-mb``, so an allocation
for a claimed count (a header saying 10^9 frames) fails at once, as a MemoryError, i.e. unexpected; the peak RSS
of the workers is reported. The ``huge_claims`` inputs (``tests.fuzzing.huge_claims``) are then read once more
each under tracemalloc: the largest traced peak and the slowest read are reported.

Printed as JSON and written to ``benchmarks/out/fuzz.json``. Run from the repository root:
``python benchmarks/fuzz.py [--inputs 100000] [--seed 0] [--workers 2]``.
"""

from __future__ import annotations

import argparse
import faulthandler
import json
import os
import random
import resource
import signal
import subprocess
import sys
import tempfile
import time
import tracemalloc
import warnings
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from tqdm import tqdm  # noqa: E402

from pipeline.io.files import write_json  # noqa: E402
from stages.common import load_params, mocap_root  # noqa: E402
from pipeline.io.readers.bvh import _motion  # noqa: E402
from tests.fuzzing import (  # noqa: E402
    Harness,
    Outcome,
    check_motion_parser,
    fuzz_input,
    huge_claims,
    load_seeds,
    motion_parser_case,
    motion_parser_expected,
    read_claim,
    tmp_dir,
)

OUT = REPO / "benchmarks" / "out" / "fuzz.json"
TARGET_INPUTS = 100_000
CLAIM_PEAK_MB = 50  # a reader turning away a 10^9-frame claim may trace this much, not gigabytes
EXAMPLES = 5  # unexpected inputs listed per exception type
PARSER_CASES = 2  # token soups per input for the C MOTION parser alone (tests.fuzzing.motion_parser_case)
MOTION_PARSER_BUILT = _motion is not None  # else the reader parses with Arrow, and there is no C to fuzz alone


class InputTimeout(Exception):
    """One input ran past --timeout (a hang or quadratic behaviour): counted as unexpected."""


_worker: dict = {}


def _start_worker(mocap: str, run_seed: int, timeout: float, headroom_mb: int, work_dir: str) -> None:
    faulthandler.enable()
    warnings.simplefilter("ignore")  # mutated numbers overflow casts by the thousand; outcomes are what counts
    seeds = load_seeds(Path(mocap))
    harness = Harness(Path(work_dir))
    harness.run(seeds[0], seeds[0].data)  # warm the lazy imports before the footprint is measured
    data_kb = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmData:"))
    limit = (data_kb * 1024) + headroom_mb * 2**20
    resource.setrlimit(resource.RLIMIT_DATA, (limit, limit))

    def _alarm(signum, frame):
        raise InputTimeout(f"over {timeout:g} s")

    signal.signal(signal.SIGALRM, _alarm)
    _worker.update(seeds=seeds, harness=harness, run_seed=run_seed, timeout=timeout,
                   baseline_kb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                   progress=Path(work_dir) / f"{os.getpid()}.current")


def _run_one(index: int) -> tuple[dict, Outcome, float]:
    seed, data, mutations = fuzz_input(_worker["seeds"], _worker["run_seed"], index)
    signal.setitimer(signal.ITIMER_REAL, _worker["timeout"])
    start = time.perf_counter()
    try:
        outcome = _worker["harness"].run(seed, data)
    except InputTimeout as err:  # raised outside the harness' own try
        outcome = Outcome("unexpected", f"InputTimeout: {err}")
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    info = {"index": index, "seed": seed.name, "format": seed.format, "bytes": len(data), "mutations": mutations}
    return info, outcome, time.perf_counter() - start


def _run_parser_cases(index: int) -> tuple[int, list[dict]]:
    """The C MOTION parser on input ``index``'s own token soups: (how many it accepted, mismatches)."""
    accepted, wrong = 0, []
    for case in range(index * PARSER_CASES, (index + 1) * PARSER_CASES) if MOTION_PARSER_BUILT else ():
        data, frames, channels = motion_parser_case(random.Random(f"{_worker['run_seed']}:parser:{case}"))
        try:
            check_motion_parser(data, frames, channels)
        except AssertionError as err:
            wrong.append({"index": index, "parser_case": case, "error": f"MotionParserMismatch: {err}",
                          "stage": "screen"})
        accepted += motion_parser_expected(data, frames, channels) is not None
    return accepted, wrong


def _run_chunk(indices: range) -> dict:
    """Fuzz ``indices``; counts, unexpected inputs, timing and memory of this worker so far."""
    counts: Counter = Counter()
    reasons: dict[str, Counter] = defaultdict(Counter)
    mutators: Counter = Counter()
    unexpected, slowest, rss_step = [], (0.0, None), (0, None)
    parser = Counter(cases=len(indices) * PARSER_CASES * MOTION_PARSER_BUILT)
    for index in indices:
        _worker["progress"].write_text(str(index))  # read by the parent if this process dies mid-input
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        info, outcome, seconds = _run_one(index)
        step = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before
        accepted, wrong = _run_parser_cases(index)
        parser["accepted"] += accepted
        unexpected += wrong
        counts[(info["format"], outcome.kind)] += 1
        if not outcome.unexpected:
            reasons[info["format"]][f"{outcome.kind}: {outcome.detail}"] += 1
        mutators.update(m.split("(")[0].split("=")[0].split("@")[0] for m in info["mutations"])
        if outcome.unexpected:
            unexpected.append({**info, "error": outcome.detail, "stage": outcome.stage})
        slowest = max(slowest, (seconds, info), key=lambda s: s[0])
        rss_step = max(rss_step, (step, info), key=lambda s: s[0])
    return {"counts": counts, "reasons": reasons, "mutators": mutators, "unexpected": unexpected, "parser": parser,
            "slowest": slowest, "rss_step": rss_step, "pid": os.getpid(),
            "baseline_kb": _worker["baseline_kb"], "maxrss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}


def fuzz(mocap: Path, run_seed: int, inputs: int, workers: int, chunk: int, timeout: float,
         headroom_mb: int, work_dir: Path) -> tuple[list[dict], list[dict]]:
    """Run every input on ``workers`` processes: (chunk results, inputs that killed a process). ``work_dir``
    holds the workers' inputs and progress files."""
    todo = [range(a, min(a + chunk, inputs)) for a in range(0, inputs, chunk)]
    results, crashes = [], []
    init = (str(mocap), run_seed, timeout, headroom_mb, str(work_dir))
    with tqdm(total=inputs, unit="input", file=sys.stderr) as bar:
        while todo:
            with ProcessPoolExecutor(workers, initializer=_start_worker, initargs=init) as pool:
                futures = {pool.submit(_run_chunk, c): c for c in todo}
                todo = []
                for future in as_completed(futures):
                    try:
                        results.append(future.result())
                        bar.update(len(futures[future]))
                    except BrokenProcessPool:  # a worker died: every unfinished chunk comes back
                        todo.append(futures[future])
            if todo:  # find the input that kills a process, count it, and rerun the rest without it
                killers = [i for i in _current_inputs(work_dir) if _kills(run_seed, i)]
                if not killers:
                    raise RuntimeError("a fuzz worker died and no input it was on kills a process when rerun")
                crashes += [{"index": i, "error": "ProcessDied: the input kills the process (segfault or abort)",
                             "stage": "process"} for i in killers]
                todo = [part for c in todo for part in _split(c, killers)]
                bar.update(len(killers))
    return results, crashes


def _current_inputs(work_dir: Path) -> list[int]:
    """The input each worker was on when the pool broke (read, then cleared)."""
    indices = []
    for path in work_dir.glob("*.current"):
        indices.append(int(path.read_text()))
        path.unlink()
    return sorted(indices)


def _kills(run_seed: int, index: int) -> bool:
    """Whether input ``index`` kills a fresh process (by a signal) when run alone."""
    probe = subprocess.run([sys.executable, __file__, "--seed", str(run_seed), "--probe", str(index)],
                           capture_output=True)
    return probe.returncode < 0


def _split(indices: range, killers: list[int]) -> list[range]:
    parts, start = [], indices.start
    for k in sorted(i for i in killers if i in indices):
        parts.append(range(start, k))
        start = k + 1
    parts.append(range(start, indices.stop))
    return [p for p in parts if len(p)]


def claims(mocap: Path) -> dict:
    """Read every huge-claim input under tracemalloc: outcomes, largest traced peak, slowest read."""
    outcomes: Counter = Counter()
    peak_mb, worst, slowest = 0.0, None, 0.0
    items = huge_claims(load_seeds(mocap))
    for what, seed, data in items:
        tracemalloc.start()
        start = time.perf_counter()
        try:
            outcome = read_claim(seed.format, data)
        except Exception as err:  # noqa: BLE001 - reported, never fatal
            outcome = f"unexpected {type(err).__name__}"
        seconds = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        outcomes[f"{seed.format} {what}: {outcome}"] += 1
        slowest = max(slowest, seconds)
        if peak > peak_mb:
            peak_mb, worst = peak, f"{seed.name} {what}"
    return {"inputs": len(items), "outcomes": dict(sorted(outcomes.items())), "tracemalloc_peak_mb_max":
            round(peak_mb, 2), "peak_input": worst, "seconds_max": round(slowest, 3), "limit_mb": CLAIM_PEAK_MB}


def summarise(results: list[dict], crashes: list[dict], inputs: int, wall: float, args) -> dict:
    counts: Counter = Counter()
    reasons: dict[str, Counter] = defaultdict(Counter)
    mutators: Counter = Counter()
    parser: Counter = Counter()
    for r in results:
        parser.update(r["parser"])
        counts.update(r["counts"])
        mutators.update(r["mutators"])
        for fmt, c in r["reasons"].items():
            reasons[fmt].update(c)
    unexpected = [u for r in results for u in r["unexpected"]] + crashes
    by_type: dict[str, dict] = {}
    for u in sorted(unexpected, key=lambda u: u["index"]):
        kind = u["error"].split(":")[0]
        entry = by_type.setdefault(kind, {"count": 0, "examples": []})
        entry["count"] += 1
        if len(entry["examples"]) < EXAMPLES:
            entry["examples"].append(u)
    workers = {r["pid"]: r for r in results}
    baseline = max((r["baseline_kb"] for r in workers.values()), default=0) / 1024
    peak = max((r["maxrss_kb"] for r in results), default=0) / 1024
    slowest = max((r["slowest"] for r in results), key=lambda s: s[0], default=(0.0, None))
    step = max((r["rss_step"] for r in results), key=lambda s: s[0], default=(0, None))
    outcomes = Counter()
    by_format: dict[str, Counter] = defaultdict(Counter)
    for (fmt, kind), n in counts.items():
        outcomes[kind] += n
        by_format[fmt][kind] += n
    outcomes["unexpected"] += len(crashes)
    mismatches = sum(1 for u in unexpected if "parser_case" in u)  # counted in "unexpected", not per input
    return {
        "inputs": inputs,
        "seed": args.seed,
        "workers": args.workers,
        "outcomes": dict(sorted(outcomes.items())),
        "outcomes_by_format": {f: dict(sorted(c.items())) for f, c in sorted(by_format.items())},
        "unexpected": len(unexpected),
        "unexpected_by_stage": dict(sorted(Counter(u["stage"] for u in unexpected).items())),
        "unexpected_by_type": by_type,
        "top_reasons": {f: _top_reasons(c) for f, c in sorted(reasons.items())},
        "mutations_applied": dict(mutators.most_common()),
        "motion_parser": {"cases": parser["cases"], "accepted": parser["accepted"], "mismatches": mismatches},
        "memory": {"rss_after_start_mb": round(baseline, 1), "rss_peak_mb": round(peak, 1),
                   "rss_growth_mb": round(peak - baseline, 1), "largest_rss_step_mb": round(step[0] / 1024, 1),
                   "largest_rss_step_input": step[1], "rlimit_data_headroom_mb": args.headroom_mb},
        "slowest_input": {"seconds": round(slowest[0], 3), **(slowest[1] or {})},
        "wall_s": round(wall, 1),
        "inputs_per_s": round(inputs / wall, 1) if wall else None,
    }


def _top_reasons(reasons: Counter, per_kind: int = 6) -> dict[str, list[dict]]:
    """The commonest reasons of each outcome kind (numbers and paths masked, so reasons of a kind group)."""
    out: dict[str, list[dict]] = defaultdict(list)
    for reason, n in reasons.most_common():
        kind, _, text = reason.partition(": ")
        if len(out[kind]) < per_kind:
            out[kind].append({"count": n, "reason": text})
    return dict(sorted(out.items()))


def replay(mocap: Path, run_seed: int, index: int) -> None:
    """Rerun one input in this process, with the traceback of whatever it raises, and keep its bytes."""
    import traceback

    from pipeline.ingest.run import ingest_chunk
    from pipeline.io.files import sha256_bytes

    seed, data, mutations = fuzz_input(load_seeds(mocap), run_seed, index)
    harness = Harness()
    path = harness.root / seed.source / seed.rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    # Outside the repository: the bytes are a real file's, under its licence (tests check no mocap lands there).
    keep = Path(tempfile.gettempdir()) / f"emogait-fuzz-{run_seed}-{index}{Path(seed.rel).suffix}"
    keep.write_bytes(data)
    print(f"input {index} of run {run_seed}: {seed.name}, mutations {mutations}; bytes kept in {keep}")
    try:
        result = ingest_chunk(harness.manifests[seed.source], harness.skeleton, [(seed.rel, sha256_bytes(data))],
                              harness.cfg)
        print(result.records)
    except Exception:  # noqa: BLE001
        traceback.print_exc()
    print(harness.run(seed, data))


def main() -> dict | None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--inputs", type=int, default=TARGET_INPUTS)
    parser.add_argument("--seed", type=int, default=0, help="run seed: with the index, fixes every input")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--chunk", type=int, default=500, help="inputs per task")
    parser.add_argument("--timeout", type=float, default=20.0, help="seconds one input may take")
    parser.add_argument("--headroom-mb", type=int, default=1536, help="RLIMIT_DATA above a worker's start-up footprint")
    parser.add_argument("--replay", type=int, metavar="INDEX", help="rerun one input here and print its traceback")
    parser.add_argument("--probe", type=int, metavar="INDEX", help=argparse.SUPPRESS)  # crash check, see _kills
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    mocap = mocap_root(load_params())
    if args.replay is not None:
        replay(mocap, args.seed, args.replay)
        return None
    if args.probe is not None:
        _worker.update(seeds=load_seeds(mocap), harness=Harness(), run_seed=args.seed)
        _worker["harness"].run(*fuzz_input(_worker["seeds"], args.seed, args.probe)[:2])
        _run_parser_cases(args.probe)
        return None
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="emogait-fuzz-", dir=tmp_dir()) as work_dir:
        results, crashes = fuzz(mocap, args.seed, args.inputs, args.workers, args.chunk, args.timeout,
                                args.headroom_mb, Path(work_dir))
    wall = time.perf_counter() - start
    result = summarise(results, crashes, args.inputs, wall, args)
    result["huge_claims"] = claims(mocap)
    beyond_screen = result["unexpected_by_stage"].get("ingest", 0)
    result["acceptance"] = {
        "inputs_at_least_100000": args.inputs >= TARGET_INPUTS,
        "zero_unexpected_readers_and_screen": result["unexpected"] - beyond_screen == 0,
        "zero_unexpected_whole_ingest": result["unexpected"] == 0,
        "bounded_memory": result["huge_claims"]["tracemalloc_peak_mb_max"] < CLAIM_PEAK_MB
        and not any("MemoryError" in k for k in result["unexpected_by_type"]),
    }
    write_json(result, args.out)
    print(json.dumps(result, indent=2, sort_keys=True, default=str))
    return result


if __name__ == "__main__":
    main()

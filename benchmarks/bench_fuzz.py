"""Fuzz replay with seeded damaged copies of real and simulated logs: crashes, hangs, samples recovered.

Every format replay reads (.tlog, .bin, .ulg, DataFlash text .log, CSV) is damaged in eight ways in turn
(byte flips, 0.2–0.6 % of the bits flipped, truncation, inserted, zeroed and duplicated blocks, a
destroyed header, a damaged format definition: ``mav_motor_health.evaluation.damage``), and each copy is
read and diagnosed as replay does. A clear project error (a file with nothing left to diagnose) is a
correct answer; any other exception is a crash, and no answer within the time limit a hang. Two fixed
checks per log follow: truncation at 90 % of the file, and one flipped byte (each byte position drawn
by seed), with the share of the intact file's samples recovered. Last, resynchronisation's cost: a
heavily bit-flipped .bin against its clean read, same run.

    PYTHONPATH=src python benchmarks/bench_fuzz.py                 # 1,250 damaged copies (about 3 min)
    PYTHONPATH=src python benchmarks/bench_fuzz.py --per-log 40    # quicker
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from mav_motor_health.evaluation.damage import (
    DAMAGE_KINDS,
    count_samples,
    damaged_copies,
    dataflash_text,
    run_case,
)

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / "shared" / "real_logs"
LOGS = [
    ROOT / "sitl_logs" / "flight_healthy_long.tlog",
    ROOT / "sitl_logs" / "flight_F4.1_moderate.bin",
    ROOT / "sitl_logs" / "flight_F4.1_moderate.csv",
    REAL / "px4" / "esc_status_log.ulg",
    REAL / "ardupilot" / "mechanical_fail.log",  # DataFlash text without ESC records: crashes and hangs only
]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-log", type=int, default=250, help="damaged copies per log (default 250)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--limit-s", type=float, default=60.0, help="a case taking longer is a hang")
    args = parser.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="mmh-fuzz-"))
    # no public DataFlash text log carries ESC records: a text rendering of the simulated .bin does
    rendered = work / "flight_F4.1_moderate_text.log"
    rendered.write_text(dataflash_text(ROOT / "sitl_logs" / "flight_F4.1_moderate.bin"), encoding="utf-8")
    outcomes: Counter[str] = Counter()
    failures: list[str] = []
    print(
        f"{'log':<28}{'cases':>6}{'ok':>6}{'error':>7}{'crash':>7}{'hang':>6}  kept (median / worst, ok cases)"
    )
    fixed_rows = []
    for log in [*LOGS, rendered]:
        if not log.exists():
            print(f"{log.name:<28} missing: {log}", file=sys.stderr)
            continue
        data = log.read_bytes()
        try:
            intact = count_samples(log)
        except Exception:  # a log with no ESC telemetry: crash and hang checks only
            intact = 0
        counts: Counter[str] = Counter()
        kept: list[float] = []
        for case in damaged_copies(data, log.suffix, args.seed, args.per_log):
            path = work / f"case{log.suffix}"
            path.write_bytes(case.data)
            result = run_case(path, args.limit_s)
            counts[result.outcome] += 1
            if result.outcome == "ok" and intact:
                kept.append(result.samples / intact)
            if result.outcome in ("crash", "hang"):
                failures.append(f"{log.name} {case.kind} seed {case.seed}: {result.message.strip()}")
        outcomes.update(counts)
        share = f"{100 * statistics.median(kept):.2f} / {100 * min(kept):.2f} %" if kept else "—"
        print(
            f"{log.name:<28}{sum(counts.values()):>6}{counts['ok']:>6}{counts['error']:>7}"
            f"{counts['crash']:>7}{counts['hang']:>6}  {share}"
        )
        if intact:
            fixed_rows.append((log, data, intact))
    total = sum(outcomes.values())
    print(
        f"\n{total} damaged logs ({', '.join(DAMAGE_KINDS)}): {outcomes['crash']} tracebacks, "
        f"{outcomes['hang']} hangs, {outcomes['error']} clear errors"
    )
    print("\nfixed checks (samples kept of the intact file's):")
    print(f"{'log':<28}{'truncated at 90 %':>20}{'one flipped byte (worst of 20)':>34}")
    rng = np.random.default_rng(args.seed)
    for log, data, intact in fixed_rows:
        path = work / f"fixed{log.suffix}"
        path.write_bytes(data[: int(0.9 * len(data))])
        truncated = run_case(path, args.limit_s)
        flips = []
        for _ in range(20):
            buf = bytearray(data)
            buf[int(rng.integers(0, len(buf)))] ^= int(rng.integers(1, 256))
            path.write_bytes(bytes(buf))
            r = run_case(path, args.limit_s)
            flips.append(r.samples / intact if r.outcome == "ok" else 0.0)
            if r.outcome in ("crash", "hang"):
                failures.append(f"{log.name} one flipped byte: {r.message.strip()}")
        cut = truncated.samples / intact if truncated.outcome == "ok" else 0.0
        print(f"{log.name:<28}{100 * cut:>19.2f}%{100 * min(flips):>33.3f}%")
    resync = _resync_ratio(work)
    if resync is not None:
        print(
            f"\nresynchronisation: {resync[0]} with 0.4 % of its bits flipped (past its first 200 kB of formats)"
            f" reads in {resync[1]:.2f}x the time of the clean file ({resync[2]:.2f} s vs {resync[3]:.2f} s)"
        )
    for failure in failures[:10]:
        print("\nFAILURE " + failure)
    return 1 if failures else 0


def _resync_ratio(work: Path) -> tuple[str, float, float, float] | None:
    from mav_motor_health.telemetry import sources

    log = REAL / "ardupilot_sitl" / "hexa_motor1_half.bin"
    if not log.exists():
        return None
    data = log.read_bytes()
    rng = np.random.default_rng(4)
    bits = rng.choice(np.arange(200_000 * 8, len(data) * 8), size=int(0.004 * len(data) * 8), replace=False)
    arr = np.frombuffer(data, dtype=np.uint8).copy()
    np.bitwise_xor.at(arr, bits // 8, (1 << (bits % 8)).astype(np.uint8))
    damaged = work / "flipped.bin"
    damaged.write_bytes(arr.tobytes())

    def best_of(path: Path, n: int = 3) -> float:
        times = []
        for _ in range(n):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t = time.perf_counter()
                sources.read(path)
                times.append(time.perf_counter() - t)
        return min(times)

    clean, flipped = best_of(log), best_of(damaged)
    return log.name, flipped / clean, flipped, clean


if __name__ == "__main__":
    raise SystemExit(main())

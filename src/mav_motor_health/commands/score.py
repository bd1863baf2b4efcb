"""``mav-motor-health score RESULTS TRUTH``: a diagnosis against the simulator's ground truth."""

from __future__ import annotations

import argparse
import json

from ..evaluation.score import format_score, read_diagnosis, read_truth, score


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "score",
        help="score a diagnosis CSV against a simulator truth file, beside the paper's results",
        description="RESULTS: a diagnosis CSV (time_s,motor,state,announced,steady,...) as replay or "
        "diagnose write it; TRUTH: the .truth.json written next to a simulated log.",
    )
    p.add_argument("results", help="diagnosis CSV")
    p.add_argument("truth", help="ground-truth JSON sidecar")
    p.add_argument("--json", action="store_true", help="print the scores as JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    truth = read_truth(args.truth)
    result = score(read_diagnosis(args.results), truth)
    print(json.dumps(result.to_dict(), indent=2) if args.json else format_score(result, truth))
    return 0

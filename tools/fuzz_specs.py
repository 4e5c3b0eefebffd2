"""Fuzz cdpm with mutated specs, URDFs and CASPR XML files.

Each case mutates a shipped model (tests/fuzzing.py: spec values replaced
by junk, keys deleted or added, URDF attributes replaced, DTDs added) or,
with ``--caspr``, a model of CASPR's library (attributes and texts replaced,
elements dropped or repeated 200 times, unknown encodings, entities),
loads (imports) and analyses it, and checks that cdpm gives its own error
(a message of at most 4000 characters) or finite verdicts and margins,
within 10 s. Prints the count of each outcome and every failure with its
seed.

Run: ``python tools/fuzz_specs.py [--cases 3000] [--seed 0] [--caspr [LIBRARY]]``
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.fuzzing import MODELS, make_case, run_case  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=3000, help="number of cases (default 3000)")
    parser.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    parser.add_argument(
        "--caspr",
        nargs="?",
        const="../shared/caspr-models/models",
        metavar="LIBRARY",
        help="fuzz CASPR XML from this model library instead (default ../shared/caspr-models/"
        "models)",
    )
    args = parser.parse_args()
    if args.caspr:
        return _fuzz_caspr(args)
    warnings.simplefilter("ignore")
    outcomes: Counter = Counter()
    failures = []
    slowest = (0.0, None)
    start = time.perf_counter()
    for k in range(args.cases):
        seed = args.seed + k
        model = MODELS[seed % len(MODELS)]
        with tempfile.TemporaryDirectory() as folder:
            spec = make_case(model, seed, Path(folder))
            t0 = time.perf_counter()
            try:
                outcome = run_case(spec)
            except AssertionError as exc:
                failures.append((seed, model.name, str(exc).replace(folder, "<case>")[:300]))
                outcomes["FAILED"] += 1
            else:
                outcomes[outcome.kind] += 1
            took = time.perf_counter() - t0
            slowest = max(slowest, (took, seed))
    print(f"{args.cases} cases in {time.perf_counter() - start:.0f} s: {dict(outcomes)}")
    print(f"slowest case: {slowest[0]:.2f} s (seed {slowest[1]})")
    for seed, model, message in failures:
        print(f"seed {seed} ({model}): {message}")
    return 1 if failures else 0


def _fuzz_caspr(args) -> int:
    from tests.fuzzing import caspr_models, make_caspr_case, run_caspr_case

    models = caspr_models(Path(args.caspr))
    if not models:
        print(f"no CASPR models under {args.caspr}", file=sys.stderr)
        return 2
    warnings.simplefilter("ignore")
    outcomes: Counter = Counter()
    failures = []
    start = time.perf_counter()
    for k in range(args.cases):
        seed = args.seed + k
        bodies = models[seed % len(models)]
        with tempfile.TemporaryDirectory() as folder:
            files = make_caspr_case(bodies, seed, Path(folder))
            try:
                outcomes[run_caspr_case(*files, Path(folder) / "out").kind] += 1
            except AssertionError as exc:
                failures.append((seed, bodies.name, str(exc).replace(folder, "<case>")[:300]))
                outcomes["FAILED"] += 1
    print(f"{args.cases} CASPR cases in {time.perf_counter() - start:.0f} s: {dict(outcomes)}")
    for seed, model, message in failures:
        print(f"seed {seed} ({model}): {message}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

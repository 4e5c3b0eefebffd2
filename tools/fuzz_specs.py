"""Fuzz cdpm with mutated specs, URDFs and CASPR XML files, scaled models,
hostile names, hostile requests to the viewer and the inputs that last
ended in tracebacks.

Each case of the default class mutates a shipped model (tests/fuzzing.py:
spec values replaced by junk, keys deleted or added, URDF attributes
replaced, DTDs added) or, with ``--caspr``, a model of CASPR's library
(attributes and texts replaced, elements dropped or repeated 200 times,
unknown encodings, entities), loads (imports) and analyses it, and checks
that cdpm gives its own error (a message of at most 4000 characters) or
finite verdicts and margins, within 10 s. Prints the count of each outcome
and every failure with its seed.

``--class`` picks another class of cases (tests/fuzzing.py):

- ``scale``: a shipped model with every mass times 10**k (k in -9..9) and
  every length times 10**j (j in -3..3), tension bounds [0, inf), no
  pretension: the same POC verdicts as at scale 1, or cdpm's refusal of
  magnitudes outside its range;
- ``names``: joint, cable, output and pose names that clash with map
  names, repeat, hold control characters or unicode, or are very long:
  cdpm's error naming the problem, or the name works end to end;
- ``viewer``: malformed requests to the inspection page's /api/pose (deep
  nesting, huge numbers, wrong types, not JSON, wrong Content-Type, bad
  Host, Origin, Content-Length): a 4xx and no traceback;
- ``tracebacks``: huge YAML integers, alias chains, sexagesimal numbers,
  crossed CASPR joint limits, picture dpi and titles, odd inertias.

Run: ``python tools/fuzz_specs.py [--cases 3000] [--seed 0] [--caspr [LIBRARY]]``
or ``python tools/fuzz_specs.py --class scale --cases 300``
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from collections import Counter
from contextlib import ExitStack
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.fuzzing import MODELS, make_case, run_case  # noqa: E402

#: the classes of ``--class`` besides the default ``mutate``
CLASSES = ("mutate", "scale", "names", "viewer", "tracebacks")


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
    parser.add_argument(
        "--class",
        dest="kind",
        choices=CLASSES,
        default="mutate",
        help="class of cases: mutated specs (default), scaled models, names, viewer "
        "requests, the last tracebacks",
    )
    args = parser.parse_args()
    if args.caspr:
        return _fuzz_caspr(args)
    if args.kind != "mutate":
        return _fuzz_class(args)
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


def _fuzz_class(args) -> int:
    """Run ``args.cases`` seeded cases of one class of tests/fuzzing.py."""
    import tests.fuzzing as fz

    warnings.simplefilter("ignore")
    outcomes: Counter = Counter()
    failures = []
    start = time.perf_counter()
    with ExitStack() as stack:
        if args.kind == "viewer":
            from cdpm.viewer import InspectionPage

            spec = fz.ROOT / "models" / "two_link_planar" / "two_link_planar.yaml"
            page = stack.enter_context(InspectionPage(fz.cdpm.load_robot(spec), "nominal"))
            stderr_text = stack.enter_context(fz.StderrCapture())

        def one(seed: int, folder: Path):
            """(label, outcome) of one case."""
            if args.kind == "scale":
                case = fz.make_scale_case(fz.SCALE_MODELS[seed % len(fz.SCALE_MODELS)], seed)
                label = f"{case.model.stem} 1e{case.mass_exp} kg 1e{case.length_exp} m"
                return label, lambda: fz.run_scale_case(case, folder)
            if args.kind == "names":
                case = fz.make_name_case(seed)
                return case.category, lambda: fz.run_name_case(case, folder)
            if args.kind == "viewer":
                case = fz.make_request_case(seed, page.port, fz.page_credentials(page))
                return case.what, lambda: fz.run_request_case(page.port, case, stderr_text)
            case = fz.make_traceback_case(seed)
            return case.kind, lambda: fz.run_traceback_case(case, folder)

        for k in range(args.cases):
            seed = args.seed + k
            with tempfile.TemporaryDirectory() as folder:
                label, run = one(seed, Path(folder))
                try:
                    outcome = run()
                except AssertionError as exc:
                    failures.append((seed, label, str(exc).replace(folder, "<case>")[:300]))
                    outcomes["FAILED"] += 1
                else:
                    outcomes[outcome.kind] += 1
    print(
        f"{args.cases} {args.kind} cases in {time.perf_counter() - start:.0f} s: {dict(outcomes)}"
    )
    by_label = Counter(label for _, label, _ in failures)
    if by_label:
        print("failures by kind: " + ", ".join(f"{k} {n}" for k, n in by_label.most_common()))
    for seed, label, message in failures:
        print(f"seed {seed} ({label}): {message}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

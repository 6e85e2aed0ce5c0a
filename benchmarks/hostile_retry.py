"""Re-try every hostile-input case on the command line and print what each one did.

Each case runs ``camvlp`` in a child process with 1 GB of address space and a 10 s limit
(``tests/hostile/bad_inputs.py`` makes the files and lists the cases).  Prints, per case: the
exit code, the number of stderr lines, the peak resident memory, the wall time and whether the
promise held (one ``error:`` line, the expected exit code, nothing left behind, strict JSON).

Usage: ``python benchmarks/hostile_retry.py [--timeout 10] [--keep DIR]``
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "hostile"))

from bad_inputs import api_cases, cases, problems, run_case


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds per case")
    parser.add_argument("--keep", type=Path, help="write the bad files here and keep them")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        rows = []
        for case in cases(root):
            outcome = run_case(case, timeout_s=args.timeout)
            found = problems(case, outcome)
            rows.append((case, outcome, found))
            first = next((ln for ln in outcome.stderr if ln.startswith("error: ")), "")
            print(
                f"{case.name:42s} exit {outcome.code:>3}  stderr {len(outcome.stderr)} line(s)  "
                f"peak {outcome.peak_mb:6.0f} MB  {outcome.seconds:5.2f} s  "
                f"{'ok' if not found else 'BROKEN: ' + '; '.join(found)}",
                flush=True,
            )
            if first:
                print(f"{'':42s} {first[:150]}")
    broken = [r for r in rows if r[2]]
    print(
        f"\n{len(rows)} cases, {len(rows) - len(broken)} kept the promise, {len(broken)} broke "
        f"it; peak {max(o.peak_mb for _, o, _ in rows):.0f} MB, slowest "
        f"{max(o.seconds for _, o, _ in rows):.2f} s"
    )
    api_broken = _api(Path(tempfile.mkdtemp(prefix="camvlp-hostile-api-")))
    return 1 if broken or api_broken else 0


def _api(root: Path) -> int:
    """Run each bad API call in this process; print what it raised, peak memory and time."""
    import time
    import tracemalloc

    import camvlp

    print("\nPython API")
    broken = 0
    for name, call in api_cases(root):
        tracemalloc.start()
        t0 = time.perf_counter()
        try:
            call()
            what = "returned"
        except camvlp.InputError as exc:
            what = f"InputError: {str(exc)[:90]}"
        except Exception as exc:  # the point of the benchmark: report anything else
            what = f"BROKEN {type(exc).__name__}: {str(exc)[:80]}"
            broken += 1
        seconds = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"{name:34s} peak {peak / 2**20:6.1f} MB  {seconds:5.2f} s  {what}", flush=True)
    return broken


if __name__ == "__main__":
    raise SystemExit(main())

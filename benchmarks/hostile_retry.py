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

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "hostile"))
sys.path.insert(0, str(REPO / "src"))  # this checkout's camvlp, not an installed one

from bad_inputs import api_cases, cases, problems, run_case  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds per case")
    parser.add_argument("--keep", type=Path, help="write the bad files here and keep them")
    parser.add_argument("--api-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.api_only:  # the child process of _api_in_child
        return _api(Path(tempfile.mkdtemp(prefix="camvlp-hostile-api-")), args.timeout)
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
    api_code = _api_in_child(args.timeout)
    return 1 if broken or api_code else 0


def _api_in_child(timeout_s: float) -> int:
    """Run the API cases in a child process with 1 GB of address space."""
    import resource
    import subprocess

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))

    argv = [sys.executable, __file__, "--api-only", "--timeout", str(timeout_s)]
    return subprocess.run(argv, preexec_fn=limit, check=False).returncode


class _TimedOut(Exception):
    pass


def _api(root: Path, timeout_s: float) -> int:
    """Run each bad API call (each under an alarm of ``timeout_s``); print what it raised,
    the peak memory it allocated and its time."""
    import signal
    import time
    import tracemalloc

    import camvlp

    def alarm(*_):
        raise _TimedOut

    signal.signal(signal.SIGALRM, alarm)
    print(f"\nPython API (camvlp from {Path(camvlp.__file__).parent})")
    broken = 0
    for name, call in api_cases(root):
        tracemalloc.start()
        t0 = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, timeout_s)
        try:
            call()
            what = "returned"
        except camvlp.InputError as exc:
            what = f"InputError: {str(exc)[:90]}"
        except _TimedOut:
            what = f"BROKEN: over {timeout_s:g} s"
            broken += 1
        except Exception as exc:  # the point of the benchmark: report anything else
            what = f"BROKEN {type(exc).__name__}: {str(exc)[:80]}"
            broken += 1
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        seconds = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"{name:40s} peak {peak / 2**20:6.1f} MB  {seconds:5.2f} s  {what}", flush=True)
    return broken


if __name__ == "__main__":
    raise SystemExit(main())

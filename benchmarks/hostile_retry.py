"""Re-try every hostile-input case on the command line and print what each one did.

Each case runs ``camvlp`` in a child process with 1 GB of address space and a 10 s limit
(``tests/hostile/bad_inputs.py`` makes the files and lists the cases).  Prints, per case: the
exit code, the number of stderr lines, the peak resident memory, the wall time and whether the
promise held (one ``error:`` line, the expected exit code, nothing left behind, strict JSON).
Then the Python API's bad calls (in a child process of 1 GB), and ``camvlp serve`` (on
127.0.0.1, its default timeouts) under hostile requests: per case its answers, its time, and
the slowest answer to ``/api/v1/health`` meanwhile (a client that must be served within 1 s).

Usage: ``python benchmarks/hostile_retry.py [--timeout 10] [--keep DIR] [--no-service]``
"""

from __future__ import annotations

import argparse
import json
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
    parser.add_argument("--no-service", action="store_true", help="skip camvlp serve's cases")
    parser.add_argument("--service-only", action="store_true", help="only camvlp serve's cases")
    parser.add_argument("--api-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.service_only:
        return 1 if _service() else 0
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
    service_code = 0 if args.no_service else _service()
    return 1 if broken or api_code or service_code else 0


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


# -------------------------------------------------------------------------- camvlp serve


class _Health:
    """Asks ``/api/v1/health`` every 0.2 s in a thread; the slowest answer (s) is kept."""

    def __init__(self, base: str):
        import threading

        self.base, self.slowest, self._stop = base, 0.0, threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        import time

        import httpx

        while not self._stop.wait(0.2):
            t0 = time.monotonic()
            try:
                httpx.get(f"{self.base}/api/v1/health", timeout=10).raise_for_status()
                took = time.monotonic() - t0
            except httpx.HTTPError:
                took = 10.0
            self.slowest = max(self.slowest, took)

    def __enter__(self) -> _Health:
        self.slowest = 0.0
        self._thread = type(self._thread)(target=self._run, daemon=True)
        self._stop.clear()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


def _service() -> int:
    """Start ``camvlp serve`` (one process, default limits and timeouts) and try the second
    round's hostile requests on it; print a row per case."""
    import os
    import secrets
    import socket
    import subprocess
    import time
    from concurrent.futures import ThreadPoolExecutor

    import httpx
    from bad_inputs import scan_bomb

    sys.path[:0] = [str(REPO / "tests"), str(REPO / "tests" / "service")]
    from service_helpers import CAMERA_JSON, MAP_JSON, free_port

    admin = secrets.token_urlsafe(32)
    env = {**os.environ, "CAMVLP_ADMIN_KEY": admin, "PYTHONPATH": str(REPO / "src")}
    tmp = Path(tempfile.mkdtemp(prefix="camvlp-hostile-serve-"))
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    cmd = [sys.executable, "-m", "camvlp", "serve", "--db", f"sqlite:///{tmp / 's.db'}"]
    cmd += ["--port", str(port), "--log-level", "warning"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    for _ in range(300):
        try:
            if httpx.get(f"{base}/api/v1/health", timeout=1).status_code == 200:
                break
        except httpx.HTTPError:
            time.sleep(0.1)
    print("\ncamvlp serve (127.0.0.1, one process, default limits)")
    rows: list[tuple[str, str, float, float, bool]] = []
    health = _Health(base)
    ok_site = {"name": "s", "map": MAP_JSON, "camera": CAMERA_JSON}
    bearer = {"Authorization": f"Bearer {admin}"}

    def case(name: str, run, expect) -> None:
        with health:
            t0 = time.monotonic()
            got = run()
            took = time.monotonic() - t0
        good = expect(got) and health.slowest < 1.0 and took < 60
        rows.append((name, str(got)[:60], took, health.slowest, good))
        print(
            f"{name:46s} {str(got)[:60]:60s} {took:6.2f} s  health max {health.slowest:5.2f} s"
            f"  {'ok' if good else 'BROKEN'}",
            flush=True,
        )

    def post_site(body: str, headers: dict) -> int:
        h = {**headers, "Content-Type": "application/json"}
        return httpx.post(f"{base}/api/v1/sites", content=body, headers=h, timeout=30).status_code

    site = httpx.post(f"{base}/api/v1/sites", json=ok_site, headers=bearer, timeout=30).json()
    key = {"Authorization": f"Bearer {site['api_key']}"}
    sites_url = f"{base}/api/v1/sites/{site['id']}"
    case(
        "POST /sites without the admin key",
        lambda: post_site(json.dumps(ok_site), {}),
        (401).__eq__,
    )
    deep = {**ok_site, "map": {**MAP_JSON, "notes": json.loads("[" * 40 + "]" * 40)}}
    case(
        "POST /sites, an unknown key nested 41 deep",
        lambda: post_site(json.dumps(deep), bearer),
        (422).__eq__,
    )
    lone = json.dumps(ok_site)[:-1] + ', "\\ud800": 1}'
    case("POST /sites, a lone surrogate key", lambda: post_site(lone, bearer), (422).__eq__)
    case(
        "GET /sites/{id} afterwards",
        lambda: httpx.get(sites_url, headers=key).status_code,
        (200).__eq__,
    )
    stream = f"{sites_url}/fixes/stream"
    for value, expect in (("²", 400), ("9" * 5000, 422)):
        case(
            f"Last-Event-ID {value[:12]!r}{'...' if len(value) > 12 else ''}",
            lambda v=value: (
                httpx.get(stream, headers={**key, "Last-Event-ID": v.encode()}).status_code
            ),
            expect.__eq__,
        )
    bomb = scan_bomb(20_000, 6000)

    def bombs_and_a_photo() -> str:
        def upload(data: bytes) -> tuple[int, float]:
            t0 = time.monotonic()
            r = httpx.post(
                f"{sites_url}/locate", headers=key, files={"photo": ("p.jpg", data)}, timeout=120
            )
            return r.status_code, time.monotonic() - t0

        with ThreadPoolExecutor(3) as pool:
            a, b = pool.submit(upload, bomb), pool.submit(upload, bomb)
            photo = pool.submit(upload, scan_bomb(5, 64))
            (code, took) = photo.result()
            return f"bombs {a.result()[0]} {b.result()[0]}, a photo {code} in {took:.2f} s"

    case(
        f"2 uploads of {len(bomb) / 1e6:.1f} MB, 20,000 scans, + a photo",
        bombs_and_a_photo,
        lambda g: "bombs 400 400" in g,
    )

    def big_uploads(n: int = 20, mb: int = 30) -> str:
        body = bytes(mb << 20)

        def upload(_):
            return httpx.post(
                f"{sites_url}/locate", headers=key, files={"photo": ("p.jpg", body)}, timeout=120
            ).status_code

        with ThreadPoolExecutor(n) as pool:
            codes = sorted(set(pool.map(upload, range(n))))
        rss = _peak_mb(proc.pid)
        return f"{codes}, server peak {rss:.0f} MB"

    case(
        "20 uploads of 30 MB at once",
        big_uploads,
        lambda g: int(g.split("peak ")[1].split()[0]) < 1024,
    )

    def slow(n: int = 200) -> str:
        socks = [socket.create_connection(("127.0.0.1", port)) for _ in range(n)]
        for s in socks:
            s.sendall(b"GET /api/v1/health HTTP/1.1\r\nHost: x\r\nX-Slow: ")
        closed, t0 = 0, time.monotonic()
        for s in socks:
            s.settimeout(max(0.1, 30 - (time.monotonic() - t0)))
            try:
                while s.recv(4096):
                    pass
                closed += 1
            except TimeoutError:
                pass
            s.close()
        return f"{closed}/{n} closed in {time.monotonic() - t0:.1f} s"

    case("200 connections sending headers slowly", slow, lambda g: g.startswith("200/200"))

    def chunk() -> str:
        s = socket.create_connection(("127.0.0.1", port))
        s.sendall(
            b"POST /api/v1/sites HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n"
            b"fffffffffffffffffff\r\nab"
        )
        s.settimeout(30)
        data = b""
        try:
            while part := s.recv(4096):
                data += part
        except TimeoutError:
            data += b" (still open)"
        s.close()
        return data.split(b"\r\n")[0].decode()

    case("chunk size fffffffffffffffffff", chunk, lambda g: g.startswith("HTTP/1.1 4"))
    gif = tmp / "photo.gif"
    gif.write_bytes(b"GIF89a" + bytes(2000))

    def bad_db() -> str:
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "camvlp",
                "serve",
                "--db",
                f"sqlite:///{gif}",
                "--port",
                str(free_port()),
            ],
            env=env,
            capture_output=True,
            text=True,
            timeout=60,
        )
        return f"exit {r.returncode}, {len(r.stderr.splitlines())} stderr line(s)"

    case("serve --db sqlite:///photo.gif", bad_db, "exit 2, 1 stderr line(s)".__eq__)
    proc.terminate()
    _, err = proc.communicate(timeout=30)
    traceback = "Traceback" in err.decode(errors="replace")
    broken = sum(not r[4] for r in rows) + traceback
    print(
        f"{len(rows)} service cases, {len(rows) - sum(not r[4] for r in rows)} kept the "
        f"promise; a traceback in the server's log: {traceback}"
    )
    return broken


def _peak_mb(pid: int) -> float:
    """Peak resident memory of process ``pid`` so far, MB (Linux's VmHWM)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


if __name__ == "__main__":
    raise SystemExit(main())

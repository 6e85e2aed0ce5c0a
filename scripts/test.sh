#!/usr/bin/env bash
# Set up (if needed) and run the linters and the test suite, on every core (pytest-xdist).
# Usage: bash scripts/test.sh [pytest arguments], e.g. `bash scripts/test.sh -m "not slow"` for
# the fast suite (the tests marked slow re-run end to end what faster tests already check) or
# `bash scripts/test.sh tests/model -x`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check src tests benchmarks examples
.venv/bin/ruff format --check src tests benchmarks examples
.venv/bin/lint-imports --no-cache  # the layers and the stages' order ([tool.importlinter])
# --dist worksteal: a worker that has run out of tests takes some of the other's queue, so the
# two finish together (the tests marked long run first: tests/conftest.py).
# one thread each for OpenBLAS and OpenMP: every xdist worker has a core of its own, and a
# second thread would only contend for the other worker's (tests/conftest.py sets OpenCV's)
OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 .venv/bin/python -m pytest -q -n auto --dist worksteal "$@"

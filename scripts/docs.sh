#!/usr/bin/env bash
# Build the documentation site into site/ with mkdocs --strict (any warning fails): sets up
# .venv (if needed) and installs the docs extra into it (scripts/setup.sh).
# Usage: bash scripts/docs.sh [mkdocs build arguments]; `.venv/bin/mkdocs serve` previews it.
set -euo pipefail
cd "$(dirname "$0")/.."
EXTRAS=docs bash scripts/setup.sh
export NO_MKDOCS_2_WARNING=1 DISABLE_MKDOCS_2_WARNING=true  # the tools' notices about their future
.venv/bin/mkdocs build --strict --site-dir site "$@"

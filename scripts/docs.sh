#!/usr/bin/env bash
# Build the documentation site into site/ with mkdocs --strict (any warning fails): sets up
# .venv (if needed) and installs the docs extra into it (if needed).
# Usage: bash scripts/docs.sh [mkdocs build arguments]; `.venv/bin/mkdocs serve` previews it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if ! .venv/bin/python -c "import mkdocs, material, mkdocstrings_handlers.python, mkdocs_gen_files, mkdocs_literate_nav" 2>/dev/null; then
  .venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".[docs]"
fi
export NO_MKDOCS_2_WARNING=1 DISABLE_MKDOCS_2_WARNING=true  # the tools' notices about their future
.venv/bin/mkdocs build --strict --site-dir site "$@"

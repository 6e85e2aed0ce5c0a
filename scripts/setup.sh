#!/usr/bin/env bash
# Create .venv (if needed) and install camvlp with the extras in $EXTRAS into it ("dev", the
# test tools, unless given; e.g. EXTRAS=dev,docs). Skipped when .venv already holds this
# pyproject.toml's install with each of those extras (a stamp in .venv records them).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
EXTRAS=${EXTRAS:-dev}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
stamp=.venv/.camvlp-setup
hash=$(sha256sum pyproject.toml | cut -d' ' -f1)
needed=0
for extra in ${EXTRAS//,/ }; do
  grep -qxF "$hash $extra" "$stamp" 2>/dev/null || needed=1
done
[ "$needed" = 0 ] && exit 0
.venv/bin/python -m pip install --quiet --disable-pip-version-check --upgrade pip
.venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".[$EXTRAS]"
for extra in ${EXTRAS//,/ }; do
  echo "$hash $extra" >>"$stamp"
done

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
pip=(.venv/bin/python -m pip --disable-pip-version-check)
# uv installs what pip would some five times faster (4 s against 25 s for dev,docs from a
# warm cache); pip's own settings (wheel folders, indexes, constraints, certificates) are
# passed on to it, and pip does the install when uv cannot
uv_args=()
while IFS='=' read -r key value; do
  value=${value#\'}
  value=${value%\'}
  case "${key##*.}" in
    find-links) for v in $value; do uv_args+=(--find-links "$v"); done ;;
    index-url) uv_args+=(--index-url "$value") ;;
    extra-index-url) for v in $value; do uv_args+=(--extra-index-url "$v"); done ;;
    constraint) for v in $value; do uv_args+=(--constraint "$v"); done ;;
    cert) export SSL_CERT_FILE="$value" ;;
  esac
done < <("${pip[@]}" config list 2>/dev/null)
if ! { "${pip[@]}" install --quiet uv 2>/dev/null &&
  .venv/bin/uv pip install --quiet --python .venv/bin/python "${uv_args[@]}" -e ".[$EXTRAS]"; }; then
  echo "setup: uv could not install; pip does" >&2
  "${pip[@]}" install --quiet --upgrade pip
  "${pip[@]}" install --quiet -e ".[$EXTRAS]"
fi
for extra in ${EXTRAS//,/ }; do
  echo "$hash $extra" >>"$stamp"
done

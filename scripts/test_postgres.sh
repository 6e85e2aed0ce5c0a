#!/usr/bin/env bash
# Run the service's API tests against PostgreSQL: a throwaway cluster (Debian's postgresql
# package) started in a temporary folder, listening on 127.0.0.1 only, stopped at the end.
# Without PostgreSQL's programs it says so in one line and exits 0 (the SQLite run stands).
# Usage: bash scripts/test_postgres.sh [pytest arguments]
set -euo pipefail
cd "$(dirname "$0")/.."
PG_BIN=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1 || true)
if [ -z "$PG_BIN" ] || [ ! -x "$PG_BIN/initdb" ]; then
  echo "PostgreSQL is not installed: the API suite's PostgreSQL run is skipped"
  exit 0
fi
bash scripts/setup.sh
DIR=$(mktemp -d /tmp/camvlp-pg.XXXXXX)
PORT=$(.venv/bin/python -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
as_owner() { "$@"; }
if [ "$(id -u)" = 0 ]; then  # PostgreSQL does not run as root: as its own user
  chown postgres "$DIR"
  as_owner() { runuser -u postgres -- "$@"; }
fi
stop() {
  as_owner "$PG_BIN/pg_ctl" -D "$DIR/data" -m immediate stop >/dev/null 2>&1 || true
  rm -rf "$DIR"
}
trap stop EXIT
as_owner "$PG_BIN/initdb" -D "$DIR/data" -A trust -U camvlp --no-sync >/dev/null
as_owner "$PG_BIN/pg_ctl" -D "$DIR/data" -l "$DIR/log" -w start -o \
  "-c listen_addresses=127.0.0.1 -p $PORT -k $DIR -c fsync=off -c synchronous_commit=off -c full_page_writes=off" \
  >/dev/null
as_owner "$PG_BIN/createdb" -h 127.0.0.1 -p "$PORT" -U camvlp camvlp_test
echo "$("$PG_BIN/postgres" --version) on 127.0.0.1:$PORT: the API suite"
export CAMVLP_TEST_DB_URL="postgresql+psycopg://camvlp@127.0.0.1:$PORT/camvlp_test"
.venv/bin/python -m pytest -q -p no:cacheprovider tests/service/test_api.py tests/service/test_frames_api.py \
  tests/service/test_operations.py tests/service/test_migrations.py \
  tests/service/test_locate_gravity_api.py tests/hostile/test_service.py "$@"

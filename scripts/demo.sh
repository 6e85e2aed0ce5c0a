#!/usr/bin/env bash
# Set up (if needed), render a photo of the thesis' room, locate the camera in it, and write
# an annotated picture.  Everything goes to out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
CAMVLP=.venv/bin/camvlp
OUT=out/demo
mkdir -p "$OUT"
POSITION=0.12,0,-0.08   # metres, on the floor (y = 0), under the lights
EULER=92,3,25            # degrees: looking up at the ceiling, tilted 2 and 3 deg, 25 deg of roll
echo "== render: camera at ($POSITION) m, theta = ($EULER) deg"
"$CAMVLP" render --camera examples/thesis_camera.yaml --map examples/thesis_room.yaml \
  --position "$POSITION" --euler "$EULER" --seed 7 --out "$OUT/photo.jpg"
echo
echo "== locate"
"$CAMVLP" locate "$OUT/photo.jpg" --camera examples/thesis_camera.yaml \
  --map examples/thesis_room.yaml --annotate "$OUT/annotated.jpg"
echo
echo "true position ($POSITION) m; wrote $OUT/photo.jpg, $OUT/photo.json (truth), $OUT/annotated.jpg"

"""How far off the stress benchmark's lamps are centred, and the photos' positions.

Replays ``benchmarks/stress_decode.py``'s photos (the same seeds, with looks: hot cores and
halos in half the photos) and compares each decoded lamp's centre with the render's truth, and
each located photo's position with the camera's (at the origin). Prints the centre errors'
median, percentiles and counts over 1, 2 and 5 px (all lamps and the glowing ones), the
position errors, how often each coordinate's error is within 1, 2 and 3 of the result's own
``position_sigma``, and the lamps over 2 px.

Run: ``python benchmarks/stress_centres.py [--per-cell 4] [--seed 3] [--json out/centres.json]``;
``--phone`` (with ``--tone-given`` or ``--tone-gamma G``) takes the photos of
``stress_decode.py --phone``, processed as a phone does.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import stress_decode as sd


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--per-cell", type=int, default=4, help="photos per grid cell")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", type=Path, help="write per-lamp and per-photo results here")
    ap.add_argument("--phone", action="store_true", help="a phone camera's processing too")
    ap.add_argument(
        "--tone-given", action="store_true", help="with --phone: the camera file gives its curve"
    )
    ap.add_argument(
        "--tone-gamma", type=float, metavar="G", help="with --phone: the camera file gives G"
    )
    args = ap.parse_args()
    phone = dict(phone=args.phone, tone_given=args.tone_given, tone_gamma=args.tone_gamma)
    rng = np.random.default_rng(args.seed)
    lamps, photos = [], []
    t0 = time.perf_counter()
    for e in sd.EXPOSURES:
        for r in sd.ROWS_PER_CHIP:
            for k in range(args.per_cell):
                photo, res, cond, _, fmap, _ = sd.one_photo(rng, e, r, looks=True, **phone)
                used = [fmap.get(f.id).position for f in res.fixtures if f.used]
                photos.append(
                    dict(
                        exposure=e,
                        rows_per_chip=r,
                        k=k,
                        located=bool(res),
                        position_mm=float(1e3 * np.linalg.norm(res.position)) if res else None,
                        # each axis' error over the position's own sigma (the camera at 0)
                        z=(np.abs(res.position) / res.position_sigma).tolist()
                        if res and res.position_sigma is not None
                        else None,
                        sigma_mm=(1e3 * res.position_sigma).tolist()
                        if res and res.position_sigma is not None
                        else None,
                        # the used lamps' mean distance from the camera (at 0)
                        distance_mm=float(1e3 * np.mean(np.linalg.norm(used, axis=1)))
                        if used
                        else None,
                    )
                )
                for f in res.fixtures:
                    d = [float(np.hypot(*(t.pixel - f.pixel))) for t in photo.fixtures]
                    j = int(np.argmin(d))
                    if f.id is not None and f.id == photo.fixtures[j].id:
                        lamps.append(
                            dict(
                                exposure=e,
                                rows_per_chip=r,
                                k=k,
                                id=f.id,
                                error_px=d[j],
                                glowing=cond["halo"] > 0,
                            )
                        )
            print(
                f"exposure {e} chip, {r} rows per chip: {time.perf_counter() - t0:.0f} s",
                file=sys.stderr,
            )
    err = np.array([x["error_px"] for x in lamps])
    glow = np.array([x["glowing"] for x in lamps])
    pos = np.array([p["position_mm"] for p in photos if p["located"]])
    print(f"decoded lamps {err.size}, photos located {pos.size} of {len(photos)}")
    print(
        f"centre error px: median {np.median(err):.3f}, 90 % {np.percentile(err, 90):.3f}, "
        f"99 % {np.percentile(err, 99):.2f}, max {err.max():.2f}; over 1 px {(err > 1).sum()}, "
        f"over 2 px {(err > 2).sum()} ({(err[glow] > 2).sum()} of {glow.sum()} glowing), "
        f"over 5 px {(err > 5).sum()}"
    )
    print(
        f"position error mm: mean {pos.mean():.3f}, median {np.median(pos):.3f}, "
        f"90 % {np.percentile(pos, 90):.3f}, max {pos.max():.3f}; over 1 mm {(pos > 1).sum()}, "
        f"over 5 mm {(pos > 5).sum()}"
    )
    z = np.array([p["z"] for p in photos if p["z"] is not None]).ravel()
    if z.size:  # for normal errors: 68.3, 95.4 and 99.7 %
        within = ", ".join(f"{100 * np.mean(z <= k):.1f} % within {k} sigma" for k in (1, 2, 3))
        print(f"position against its own sigma (x, y, z of each photo): {within}")
    for x in sorted(lamps, key=lambda x: -x["error_px"]):
        if x["error_px"] <= 2:
            break
        print(
            f"  {x['error_px']:6.2f} px  exposure {x['exposure']} chip, "
            f"{x['rows_per_chip']} rows per chip, photo {x['k']}, ID {x['id']}"
        )
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(dict(lamps=lamps, photos=photos)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

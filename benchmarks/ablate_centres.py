"""How far off the stress photos' lamps are centred with some of ``locate``'s special paths
switched off: ``stress_centres.py`` run under ``ablate.py``'s switches.

``ablate.py`` counts the lamps decoded and the photos located; a path that centres lamps
(crowded, rim, radial, glow-centre) can leave those counts alone and still move centres and
positions, which this measures.  Run::

    python benchmarks/ablate_centres.py --off crowded+rim --per-cell 4 --seed 3
    python benchmarks/ablate_centres.py --per-cell 4 --seed 3      # nothing off: the baseline

and compare the two printouts (centre errors over 1, 2 and 5 px, position errors, how often
the position lies within its own sigma).  ``--list`` prints the paths.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import ablate  # (the benchmarks beside this one)
import stress_centres


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--off", default="", help="paths joined by + to switch off (none: baseline)")
    ap.add_argument("--per-cell", type=int, default=4, help="photos per grid cell")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--json", type=Path, help="write per-lamp and per-photo results here")
    ap.add_argument("--list", action="store_true", help="list the paths and exit")
    args = ap.parse_args()
    if args.list:
        for name, path in ablate.PATHS.items():
            print(f"{name:<14} {path.what}")
        return 0
    names = [n for n in args.off.split("+") if n]
    unknown = [n for n in names if n not in ablate.PATHS]
    if unknown:
        print(f"error: unknown path {unknown[0]!r} (--list prints them)", file=sys.stderr)
        return 2
    print(f"switched off: {', '.join(names) or 'nothing'}")
    argv = ["stress_centres.py", "--per-cell", str(args.per_cell), "--seed", str(args.seed)]
    if args.json:
        argv += ["--json", str(args.json)]
    sys.argv = argv
    with ablate.switched_off(names, ablate.Counter()):
        return stress_centres.main()


if __name__ == "__main__":
    raise SystemExit(main())

"""Write the example trajectories of ``camvlp render-video`` (examples/trajectories/).

* ``robot.csv`` (``examples/thesis_room.yaml``): a robot crossing the thesis' room under its
  lights at 0.5 m/s, its camera 10 cm above the floor looking straight up, from x = -0.6 m
  (all four fixtures in view) to x = 1.9 m (two: the other two leave the picture), with a
  gentle S in z and a wobble of 0.05 degrees (1 to 4 Hz).
* ``walk.csv`` (``examples/corridor_room.yaml``): a person walking along the corridor at
  1.2 m/s with a phone 1.1 m above the floor, screen down and camera up (the long side of the
  picture along the walk), from z = -1.5 to 1.5 m; the hand shakes by a few degrees (sums of
  sines at 0.7 to 2.3 Hz) and the phone bobs by 2 cm with each step.  Fixtures enter the
  picture at its far edge and leave at the near one.

    python examples/make_trajectories.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent / "trajectories"
COLUMNS = "t,x,y,z,theta_x,theta_y,theta_z"


def _write(path: Path, t, pos, eul) -> None:
    data = np.column_stack([t, pos, eul])
    np.savetxt(path, data, delimiter=",", header=COLUMNS, comments="", fmt="%.6f")
    print(f"{path}: {len(t)} poses over {t[-1] - t[0]:.2f} s")


def robot(rate_hz: float = 200.0) -> None:
    """0.5 m/s along x under the lights, 10 cm up, looking at the ceiling."""
    rng = np.random.default_rng(1)
    length, speed = 2.5, 0.5
    t = np.arange(0.0, length / speed + 1e-9, 1.0 / rate_hz)
    x = -0.6 + speed * t
    z = 0.08 * np.sin(2 * np.pi * t / 5.0)
    pos = np.column_stack([x, np.full_like(t, -0.1), z])
    heading = np.degrees(np.arctan2(np.gradient(z, t), speed))
    freqs = np.array([[1.1], [2.3], [3.7]])
    wobble = 0.05 * np.sin(2 * np.pi * (freqs * t[None, :] + rng.uniform(0, 1, (3, 1))))
    eul = np.column_stack([90 + wobble[0], wobble[1], heading + wobble[2]])
    _write(HERE / "robot.csv", t, pos, eul)


def walk(rate_hz: float = 200.0) -> None:
    """1.2 m/s along z, phone 1.1 m up, a few degrees of hand shake, a 2 cm bob per step."""
    rng = np.random.default_rng(2)
    length, speed = 3.0, 1.2
    t = np.arange(0.0, length / speed + 1e-9, 1.0 / rate_hz)
    z = -1.5 + speed * t
    step_hz = 1.9
    y = -1.1 - 0.02 * np.sin(2 * np.pi * step_hz * t)
    x = 0.03 * np.sin(np.pi * step_hz * t)
    freqs = np.array([0.7, 1.3, 2.3])
    amps = np.array([1.5, 1.0, 0.5])  # degrees per component: up to 3 degrees per axis
    phases = rng.uniform(0, 2 * np.pi, (3, 3))
    shake = np.stack(
        [
            (amps[:, None] * np.sin(2 * np.pi * freqs[:, None] * t + phases[a][:, None])).sum(0)
            for a in range(3)
        ],
        axis=1,
    )
    eul = np.column_stack([90 + shake[:, 0], shake[:, 1], 90 + shake[:, 2]])
    _write(HERE / "walk.csv", t, np.column_stack([x, y, z]), eul)


if __name__ == "__main__":
    HERE.mkdir(exist_ok=True)
    robot()
    walk()

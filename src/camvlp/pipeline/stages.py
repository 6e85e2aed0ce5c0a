"""The public stage API: what :func:`~camvlp.pipeline.locate.locate`, the video tracker and the
service run, in this order, each stage a function of the results before it.

- 0, prepare: :func:`~camvlp.pipeline.prepare.prepare` -> :class:`Prepared`;
- 1, detect: :func:`~camvlp.pipeline.lights.find_lights` -> :class:`Lights`;
- 2, profile: :func:`~camvlp.pipeline.decode.stage.read_profiles` -> :class:`Profiles`;
- 3, decode: :func:`~camvlp.pipeline.decode.stage.decode` -> :class:`Decoded`;
- 4 and 5, identify and solve: :func:`~camvlp.pipeline.identify.stage.identify_and_solve` ->
  :class:`Solved` (its pose problem, :class:`PoseProblem`, solved by :func:`solve_pose`);
- 6, report: :func:`~camvlp.pipeline.report.report` ->
  :class:`~camvlp.pipeline.results.LocateResult`.
"""

from camvlp.pipeline.decode.stage import Decoded, Profiles, decode, read_profiles
from camvlp.pipeline.identify.stage import Solved, identify_and_solve, readout_direction
from camvlp.pipeline.lights import Lights, find_lights
from camvlp.pipeline.prepare import Prepared, prepare
from camvlp.pipeline.report import report
from camvlp.pipeline.solve import PoseProblem, solve_pose

__all__ = [
    "Decoded",
    "Lights",
    "PoseProblem",
    "Prepared",
    "Profiles",
    "Solved",
    "decode",
    "find_lights",
    "identify_and_solve",
    "prepare",
    "read_profiles",
    "readout_direction",
    "report",
    "solve_pose",
]

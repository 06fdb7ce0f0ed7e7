"""Interactive 3-D viewers in the browser (viser): replay a run directory, explore a robot's
synergies. Needs the ``viewer`` extra (``pip install 'geosyn[viewer]'``); the servers bind
to 127.0.0.1 only.

- `view_run` (``geosyn view RUN_DIR``): every stored motion of a run (one robot per
  controller, each in its colour, shown or hidden by a checkbox), a time slider, play.
- `explore_robot` (``geosyn explore ROBOT``): the robot's metric-orthonormal synergies at a
  configuration, one slider per weight; the geodesic combination is recomputed and
  animated.

Why viser: a pip package whose web client ships inside the wheel (works offline), with
3-D scene nodes and GUI controls driven from Python in one API, so a slider's callback can
run geosyn's own geodesic code; MuJoCo's web tooling (WebAssembly) would have to re-run
the physics or the geometry in the browser, away from the metric and its compiled code.
"""

from geosyn.experiments.viewer.explore import explore_robot
from geosyn.experiments.viewer.replay import view_run
from geosyn.experiments.viewer.server import Viewer, ViewerUnavailable

__all__ = ["Viewer", "ViewerUnavailable", "explore_robot", "view_run"]

"""Column names of the tables passed between pipeline stages, defined once.

Coordinates: a pixel's centre (col, row) is at (col, row); in micrometres
``x_um = col · scale`` and ``y_um = −row · scale`` (x right, y up).
``bend_angle_deg`` is the unwrapped counter-clockwise rotation (in that x-right,
y-up frame) of the tip tangent relative to the base tangent, tangents pointing
from base to tip: a tube curling clockwise has a negative angle.
"""

from __future__ import annotations

# -- tracks.csv: one row per frame -------------------------------------------------
FRAME = "frame"                  # 0-based frame index
TIME = "time_s"
BEND = "bend_angle_deg"
TIP_X = "tip_x_um"
TIP_Y = "tip_y_um"
BASE_X = "base_x_um"
BASE_Y = "base_y_um"
LENGTH = "length_um"
STATUS = "status"                # "ok", or a short reason the frame was not measured
BASE_ANGLE = "base_angle_deg"    # direction of the base tangent, CCW from +x (y up)

TRACK_COLUMNS = [FRAME, TIME, BEND, TIP_X, TIP_Y, BASE_X, BASE_Y, LENGTH, STATUS, BASE_ANGLE]
STATUS_OK = "ok"

# -- centrelines.csv: long format, base → tip, ≤ 1 px apart --------------------------
S = "s_um"
X = "x_um"
Y = "y_um"
CENTRELINE_COLUMNS = [FRAME, S, X, Y]

# -- pressure log ------------------------------------------------------------------
PRESSURE = "pressure_mpa"
PRESSURE_COLUMNS = [FRAME, TIME, PRESSURE]

# -- rendered truth: the tracker's columns plus the pressure -------------------------
TRUTH_COLUMNS = [FRAME, TIME, PRESSURE, BEND, TIP_X, TIP_Y, BASE_X, BASE_Y, LENGTH, STATUS,
                 BASE_ANGLE]

# -- file names inside a tracking output / rendered scene folder ---------------------
TRACKS_FILE = "tracks.csv"
CENTRELINES_FILE = "centrelines.csv"
PRESSURE_FILE = "pressure.csv"
TRUTH_TRACKS_FILE = "truth_tracks.csv"
TRUTH_CENTRELINES_FILE = "truth_centrelines.csv"
SCENE_FILE = "scene.json"
RUN_FILE = "run.json"            # tracker settings and what was left out, and why

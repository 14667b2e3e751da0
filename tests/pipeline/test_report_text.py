"""The reports' README states what the per-frame figures show."""

import numpy as np
import pandas as pd

from pipeline.report import _growth_line


def test_the_error_growth_is_measured_from_the_per_frame_table(tmp_path):
    bend = np.linspace(0, 300, 31)
    per_frame = pd.concat([
        # measured bend 1 % ahead of the true one, turning clockwise (negative angles)
        pd.DataFrame({"scene": "ahead", "true_bend_deg": -bend, "angle_error_deg": -0.01 * bend}),
        pd.DataFrame({"scene": "flat", "true_bend_deg": bend,
                      "angle_error_deg": 0.1 * np.cos(bend)}),
    ])
    path = tmp_path / "per_frame.csv"
    per_frame.to_csv(path, index=False)
    track = pd.DataFrame({"scene": ["ahead", "flat"], "centreline_rms_px": [0.3, 0.02]})
    line = _growth_line(path, track)
    assert "+1.00 %" in line and "(ahead;" in line
    assert "In ahead the centreline sits 0.30–0.30 px" in line
    assert _growth_line(tmp_path / "missing.csv", track) == ""

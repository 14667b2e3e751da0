"""Which side of a profile another layer of the tube leaves clear
(:func:`pipeline.refine.contact_sides`): the side whose edge still places the
tube where a coil runs beside or over it."""

import numpy as np

from pipeline.refine import contact_mask, contact_sides

HW = 6.0
GAP = 0.5


def _polyline(*pieces):
    """Points GAP px apart along straight runs and arcs: each piece is
    ("line", length) or ("arc", radius, turn_deg) from the current heading."""
    z, heading = [0j], 0.0
    for piece in pieces:
        if piece[0] == "line":
            n = int(round(piece[1] / GAP))
            step = GAP * np.exp(1j * heading)
            z.extend(z[-1] + step * np.arange(1, n + 1))
        else:
            _, radius, turn = piece
            n = int(round(abs(np.radians(turn)) * radius / GAP))
            dphi = np.radians(turn) / n
            for _ in range(n):
                heading += dphi
                z.append(z[-1] + GAP * np.exp(1j * (heading - dphi / 2)))
    z = np.asarray(z)
    t = np.gradient(z)
    return z, t / np.abs(t)


def _sides(z, t, idx, reach=2.7 * HW + 2.0):
    normals = 1j * t[idx]
    return contact_sides(z, t, idx, reach=reach, gap=GAP, normals=normals, half_width=HW,
                         clear=4.0)


def test_a_coil_running_beside_the_tube_leaves_its_far_side_clear():
    # a hairpin: out along +x, round a half turn, back 14 px above (2.3 half-widths)
    z, t = _polyline(("line", 100.0), ("arc", 7.0, 180.0), ("line", 100.0))
    out = np.argmin(np.abs(z - 50))            # on the way out, at x = 50
    back = np.argmin(np.abs(z - (50 + 14j)))   # on the way back
    idx = np.array([out, back])
    contact, free = _sides(z, t, idx)
    assert contact.all()
    # each run's other layer lies on its left (+ normal): the right side is clear
    assert free.tolist() == [-1, -1]
    # the same as contact_mask says
    assert np.array_equal(contact, contact_mask(z, idx, reach=2.7 * HW + 2.0, gap=GAP,
                                                normals=1j * t[idx], half_width=HW))


def test_a_steep_crossing_or_layers_on_both_sides_leave_no_side_clear():
    # out along +x, a loop of radius 30 turning left 270 deg, then straight down
    # across the first run at x = 70, square to it
    z, t = _polyline(("line", 100.0), ("arc", 30.0, 270.0), ("line", 80.0))
    at = np.argmin(np.abs(z - 70))
    contact, free = _sides(z, t, np.array([at]))
    assert contact[0] and free[0] == 0
    # a run between two others (the middle coil of three): no side clear
    z, t = _polyline(("line", 100.0), ("arc", 7.0, 180.0), ("line", 100.0),
                     ("arc", 7.0, -180.0), ("line", 100.0))
    middle = np.argmin(np.abs(z - (50 + 14j)))
    contact, free = _sides(z, t, np.array([middle]))
    assert contact[0] and free[0] == 0
    # a coil too near to leave the far edge's search its reach: none either
    z, t = _polyline(("line", 100.0), ("arc", 1.5, 180.0), ("line", 100.0))
    contact, free = _sides(z, t, np.array([np.argmin(np.abs(z - 50))]))
    assert contact[0] and free[0] == 0


def test_no_other_layer_no_contact():
    z, t = _polyline(("line", 60.0), ("arc", 40.0, 90.0))
    contact, free = _sides(z, t, np.arange(0, z.size, 10))
    assert not contact.any() and not free.any()

"""Exact analytic test images for the tracker's unit tests.

A tube whose axis is a circular arc (or a straight line) has a closed-form
distance from any pixel centre to its axis, so the image is exact to rounding:
the edge-pair midline lies on the axis by construction. Independent of
pipeline.render on purpose: these tests pin the tracker's geometry down on
their own.
"""

from __future__ import annotations

import numpy as np
from scipy.special import erf


def arc_axis(base: complex, angle: float, length: float, kappa: float, n: int = 2001):
    """Points (px, y up) and headings of an arc from ``base`` along ``angle``."""
    s = np.linspace(0, length, n)
    phi = angle + kappa * s
    if abs(kappa) < 1e-12:
        z = base + s * np.exp(1j * angle)
    else:
        z = base + (np.exp(1j * phi) - np.exp(1j * angle)) / (1j * kappa)
    return z, phi


def _signed_position(zp, base, angle, length, kappa):
    """(arc length of the nearest axis point, signed distance to the left) per pixel."""
    if abs(kappa) < 1e-12:
        rel = (zp - base) * np.exp(-1j * angle)
        return rel.real, rel.imag
    centre = base + 1j * np.exp(1j * angle) / kappa
    rel = zp - centre
    radius = 1 / abs(kappa)
    # angle of the pixel around the centre, measured from the base direction
    start = np.angle(base - centre)
    ang = np.angle(rel * np.exp(-1j * start)) * np.sign(kappa)
    ang = np.mod(ang + np.pi / 2, 2 * np.pi) - np.pi / 2  # base at 0, allow slightly before
    s = ang * radius
    d = (radius - np.abs(rel)) * np.sign(kappa)
    return s, d


def tube_image(shape, base, angle, length, kappa, half_width, *, polarity=-1,
               background=0.8, contrast=0.35, edge_px=0.7, noise=0.0, seed=0,
               pipette_half_width=None, pipette_contrast=0.5, pipette_offset=0.0,
               pipette_taper=0.0, round_cap=False):
    """A float32 frame of one tube (and optionally a pipette behind its base).

    The tube is ``half_width`` wide on each side of the axis, with soft (erf)
    edges of scale ``edge_px``; transmitted-light looks have ``polarity`` −1.
    The pipette's contrast is ``pipette_contrast`` times the tube's, its axis
    ``pipette_offset`` px to the left of the tube's (0: coaxial); its
    half-width grows by ``pipette_taper`` px per px back from its mouth (a
    pulled pipette). The tube's end
    is a flat face at ``length``, or with ``round_cap`` a hemisphere of its
    radius whose apex lies there.
    """
    rows, cols = shape
    rr, cc = np.mgrid[0:rows, 0:cols]
    zp = cc - 1j * rr
    s, d = _signed_position(zp, base, angle, length, kappa)
    inside_len = 0.5 * (1 + erf(s / edge_px)) * 0.5 * (1 + erf((length - s) / edge_px))
    if round_cap:
        # the axis ends a radius short of the apex; past that, the distance to its end
        z, _ = arc_axis(base, angle, length - half_width, kappa, n=2)
        beyond = s > length - half_width
        d = np.where(beyond, np.abs(zp - z[-1]), d)
        inside_len = 0.5 * (1 + erf(s / edge_px))
    across = 0.5 * (1 + erf((half_width - np.abs(d)) / edge_px))
    tube = across * inside_len
    img = np.full(shape, background, dtype=float)
    img *= 1 + polarity * contrast * tube
    if pipette_half_width is not None:
        rel = (zp - base) * np.exp(-1j * angle)
        behind = 0.5 * (1 + erf(-rel.real / edge_px))
        hw = pipette_half_width + pipette_taper * np.maximum(-rel.real, 0.0)
        pip = behind * 0.5 * (1 + erf((hw - np.abs(rel.imag - pipette_offset)) / edge_px))
        img *= 1 + polarity * pipette_contrast * contrast * pip
    if noise:
        img += np.random.default_rng(seed).normal(0, noise, shape)
    return np.clip(img, 0, 1).astype(np.float32)


def profile_image(shape, base, angle, length, kappa, offsets, values, *,
                  background=None, edge_px=0.7, noise=0.0, seed=0):
    """A float32 frame of one tube whose cross-section is given as a table:
    ``values`` at signed distances ``offsets`` (px, to the left of the axis,
    increasing), linearly interpolated between them and ``background`` (default
    the table's first value) past its ends; the end is cut flat, softened
    over ``edge_px``."""
    rows, cols = shape
    rr, cc = np.mgrid[0:rows, 0:cols]
    s, d = _signed_position(cc - 1j * rr, base, angle, length, kappa)
    background = values[0] if background is None else background
    across = np.interp(d, offsets, values, left=background, right=background)
    along = 0.5 * (1 + erf(s / edge_px)) * 0.5 * (1 + erf((length - s) / edge_px))
    img = background + (across - background) * along
    if noise:
        img += np.random.default_rng(seed).normal(0, noise, shape)
    return np.clip(img, 0, 1).astype(np.float32)


def relief_image(shape, base, angle, length, kappa, half_width, *, shear=-np.pi / 4,
                 gain=0.08, blur_px=1.0, noise=0.0, seed=0, round_cap=False, lumen=0.0):
    """A float32 relief frame (differential interference contrast) of a solid tube.

    The image is ``0.5 + gain ·`` the slope along ``shear`` (rad, CCW from +x,
    y up) of the tube's optical path length 2·√(r² − d²) (px), blurred by
    ``blur_px``: lit on the flank whose inward normal faces the shear, shaded
    on the other, fading where the tube runs along it. The end is cut flat at
    ``length``, or with ``round_cap`` is a hemisphere of the tube's radius
    whose apex lies there (the path through it 2·√(r² − ρ²), ρ the distance
    from its centre). A ``lumen`` (its radius as a fraction of the tube's,
    on the axis) runs to the cap, or to the flat end's face.
    """
    from scipy.ndimage import gaussian_filter

    rows, cols = shape
    rr, cc = np.mgrid[0:rows, 0:cols]
    zp = cc - 1j * rr
    s, d = _signed_position(zp, base, angle, length, kappa)
    body = (s >= 0) & (s <= length)
    if round_cap:
        z, _ = arc_axis(base, angle, length - half_width, kappa, n=2)
        d = np.where(s > length - half_width, np.abs(zp - z[-1]), d)
        body = s >= 0
    path = 2 * np.sqrt(np.clip(half_width**2 - d**2, 0, None)) * body
    if lumen:
        s_l, d_l = _signed_position(zp, base, angle, length, kappa)
        end = length - half_width if round_cap else length
        path -= (2 * np.sqrt(np.clip((lumen * half_width) ** 2 - d_l**2, 0, None))
                 * ((s_l >= 0) & (s_l <= end)))
    path = gaussian_filter(path, blur_px)
    d_row, d_col = np.gradient(path)
    slope = d_col * np.cos(shear) - d_row * np.sin(shear)
    img = 0.5 + gain * slope
    if noise:
        img += np.random.default_rng(seed).normal(0, noise, shape)
    return np.clip(img, 0, 1).astype(np.float32)


def ramp_axis(base: complex, angle: float, length: float, k_base: float, k_tip: float,
              step: float = 0.05):
    """Points (px, y up), arc lengths and headings of an axis whose curvature
    ramps linearly from ``k_base`` at the base to ``k_tip`` at the end (1/px):
    no chain of arcs, as a tube stiffer toward its base bends."""
    s = np.arange(0.0, length + 0.5 * step, step)
    phi = angle + k_base * s + 0.5 * (k_tip - k_base) * s**2 / length
    z = base + np.concatenate([[0j], np.cumsum(np.exp(1j * 0.5 * (phi[1:] + phi[:-1]))
                                               * np.diff(s))])
    return z, s, phi


def axis_image(shape, z, s, phi, half_width, *, polarity=-1, background=0.8, contrast=0.35,
               edge_px=0.7, noise=0.0, seed=0):
    """A float32 frame of a tube along any axis given by dense points ``z``
    (px, y up; ≤ 0.1 px apart), their arc lengths ``s`` and headings ``phi``:
    each pixel takes its distance from the nearest axis point, across and
    along the heading there, as :func:`tube_image` does from an arc. Both
    ends are cut flat."""
    from scipy.spatial import cKDTree

    rows, cols = shape
    rr, cc = np.mgrid[0:rows, 0:cols]
    zp = (cc - 1j * rr).ravel()
    reach = half_width + 5 * edge_px + 1
    # (pixels farther than that from every axis point are background: their
    # index comes back as len(z), out of range)
    _, k = cKDTree(np.column_stack([z.real, z.imag])).query(
        np.column_stack([zp.real, zp.imag]), distance_upper_bound=reach)
    near = k < z.size
    k = k[near]
    rel = (zp[near] - z[k]) * np.exp(-1j * phi[k])
    along = s[k] + rel.real
    inside = np.zeros(zp.size)
    inside[near] = (0.5 * (1 + erf(along / edge_px)) * 0.5 * (1 + erf((s[-1] - along) / edge_px))
                    * 0.5 * (1 + erf((half_width - np.abs(rel.imag)) / edge_px)))
    img = background * (1 + polarity * contrast * inside.reshape(shape))
    if noise:
        img += np.random.default_rng(seed).normal(0, noise, shape)
    return np.clip(img, 0, 1).astype(np.float32)


def two_sections(k_body, k_tip, joint=0.8, length=400.0):
    """A centreline (:class:`pipeline.centreline.Curve`, base at 0, along +x)
    whose curvature steps from k_body to k_tip (1/px) at the fraction ``joint``
    of its length."""
    from pipeline.centreline import fit_to_polyline

    s = np.linspace(0.0, length, 4001)
    phi = np.where(s < joint * length, k_body * s,
                   k_body * joint * length + k_tip * (s - joint * length))
    z = np.concatenate([[0j], np.cumsum(np.exp(1j * 0.5 * (phi[1:] + phi[:-1])) * np.diff(s))])
    return fit_to_polyline(z, 0.0, n_coef=20, joints=(joint,))

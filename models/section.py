"""Cross-section of a shape-engineered microtube (paper §2.3, Fig. 1b).

Each section of the tube is an *eccentric annulus*: a circular void of radius
``r_in`` (the template radius) inside an outer circle of radius
``R = r_in + (t_t + t_b)/2`` whose centre sits ``e = (t_t - t_b)/2`` from the void
centre towards the top wall, so that the wall is ``t_t`` thick on top and ``t_b``
at the bottom.

Notation (all lengths in µm, y measured from the void centre towards the top wall)::

    A   = π (R² − r²)                      wall area
    y_c = R² e / (R² − r²)                 centroid (neutral axis) height
    d_e = y_c                              eccentricity of the void w.r.t. the neutral axis
    I   = π/4 (R⁴ − r⁴) + π R² (e − y_c)² − π r² y_c²    second moment about the centroid

``d_e`` is signed: positive when the top wall is the thicker one, i.e. when the
tube bends towards its top side. The forms below avoid differences of nearly
equal numbers: ``R² − r² = (R − r)(R + r)``, ``e − y_c = −e r² / (R² − r²)`` and
``e`` itself is computed from ``t_t − t_b`` directly, so a thickness ratio within
1e-12 of one still gives a correctly tiny, correctly signed ``d_e``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _validate


@dataclass(frozen=True)
class CrossSection:
    """Geometry of one or many eccentric-annulus cross-sections.

    Attributes
    ----------
    area_um2 : ndarray
        Wall area A, µm².
    d_e_um : ndarray
        Signed distance from the neutral axis (centroid) to the void centre, µm;
        positive when the top wall is thicker.
    inertia_um4 : ndarray
        Second moment of area I about the centroidal axis, µm⁴.
    """

    area_um2: np.ndarray
    d_e_um: np.ndarray
    inertia_um4: np.ndarray


def cross_section(r_in_um, t_top_um, t_bot_um) -> CrossSection:
    """Closed-form area, eccentricity and second moment of eccentric annuli.

    Parameters
    ----------
    r_in_um : float or array_like
        Void (template) radius, µm.
    t_top_um, t_bot_um : float or array_like
        Top and bottom wall thicknesses, µm. All inputs broadcast together.

    Returns
    -------
    CrossSection
        Arrays with the broadcast shape of the inputs.

    Raises
    ------
    ValueError
        If any input is non-positive, NaN or infinite.
    """
    r = _validate.positive("r_in_um", r_in_um)
    tt = _validate.positive("t_top_um", t_top_um)
    tb = _validate.positive("t_bot_um", t_bot_um)
    r, tt, tb = np.broadcast_arrays(r, tt, tb)
    wall = 0.5 * (tt + tb)  # R - r
    big_r = r + wall
    e = 0.5 * (tt - tb)
    r2 = r * r
    diff_sq = wall * (big_r + r)  # R² − r², without cancellation
    area = np.pi * diff_sq
    y_c = big_r * big_r * e / diff_sq
    shift = -e * r2 / diff_sq  # e − y_c
    inertia = (
        0.25 * np.pi * diff_sq * (big_r * big_r + r2)  # π/4 (R⁴ − r⁴)
        + np.pi * big_r * big_r * shift * shift
        - np.pi * r2 * y_c * y_c
    )
    return CrossSection(area_um2=area, d_e_um=y_c, inertia_um4=inertia)

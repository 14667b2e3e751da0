#!/usr/bin/env python
"""Self-checks of the alien5 truth against its own pixels.  Writes verify_report.txt.

    python verify.py [--only NAME ...]

1. conventions: a straight solid rod rendered at row 100.0 / col 80.0 (no blur, no refraction),
   its pixel values fitted by a sub-pixel model of the area-averaged profile (centre, radius);
   every look's optical image of a straight tube is centred on its axis (outer edges' midpoint);
   sign and axis conventions of the bend angle.
2. per scene (first, middle, last frame, clean render: no noise, clutter or overlays):
   a. geometry: the body's area-coverage map has its two side edges (50 % crossings along the
      truth normal) centred on the truth centreline and ro apart;
   b. optics: the clean optical image has its outer edges centred on the truth centreline;
   c. tip: the coverage map ends (50 %) at the truth tip along the tip tangent;
   d. base: the holder's end face (glass / clamp coverage, 50 %) lies at the truth base; with no
      holder the truth base lies on the border's outer pixel edge;
   e. truth files: bend angle = integral of curvature of the truth polyline; length = polyline
      length; spacing <= 0.5 px; first / last points = base / tip; the polyline agrees with an
      independent numerical integration of the curvature from the scene's settings;
   f. files: the written frames read back in order (natural sort for folders), their count, and
      they match a re-render of the same frames; the tube stays inside the image.
"""
import argparse
import glob
import json
import math
import os
import re
import sys
import time

import cv2
import numpy as np
import pandas as pd
from scipy.ndimage import map_coordinates
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import render  # noqa: E402

LINES = []
FAILS = []


def log(msg=''):
    LINES.append(msg)
    print(msg, flush=True)


def check(ok, msg):
    log(('  ok   ' if ok else '  FAIL ') + msg)
    if not ok:
        FAILS.append(msg)
    return ok


def sample(img, cols, rows, order=3):
    """Image values at sub-pixel positions (cubic spline; the optical images are smooth)."""
    return map_coordinates(img.astype(np.float64), [rows, cols], order=order, mode='nearest')


def at_points(sc, k, cols, rows, s_from=None):
    """The renderer's own body / holder indicators evaluated exactly at points (no pixels);
    with s_from only the tube's pieces beyond that arc length (e.g. the tip's, clear of a
    curl lying under it)."""
    segs, _, _ = sc.frame_segs(k)
    if s_from is not None:
        segs = [segs[0]] + [g for g in segs[1:] if g.s0 + g.l > s_from]
    return render._object_pixels(sc, k, segs, np.asarray(cols, float), -np.asarray(rows, float), 1)


def crossing_from_outside(t, p, level):
    """Positions (from the low-t end and from the high-t end) where p first reaches level."""
    out = []
    for order in (np.arange(len(t)), np.arange(len(t))[::-1]):
        pp = p[order]
        tt = t[order]
        above = np.nonzero(pp >= level)[0]
        if len(above) == 0 or above[0] == 0:
            out.append(np.nan)
            continue
        i = above[0]
        a, b = pp[i - 1], pp[i]
        f = (level - a) / (b - a) if b != a else 0.5
        out.append(tt[i - 1] + f * (tt[i] - tt[i - 1]))
    return out


def outer_edges(t, dev):
    """Outer edges of a deviation profile |I - bg|: from each end, where it first reaches half
    of its (global) peak."""
    lv = 0.5 * dev.max()
    return tuple(crossing_from_outside(t, dev, lv))


# =============================================================================== 1. conventions
def straight_cfg(**kw):
    base = dict(W=200, H=201, D_um=400.0, D_px=20.0, L_mm=3.0, bend=0.0, N=1, heading=0.0,
                holder=dict(kind='none'), entry='left', anchor=(0.0, 0.5), margin=2.0,
                lumen=1e-6, ecc=0.0, a_wall=1.5, na_g=1e9, psf=0.0, end='flat', ss=8)
    base.update(kw)
    return render.S('conventions test', '', **base)


def rod_model(params, coords, mu, S=64):
    c, R = params
    off = (np.arange(S) + 0.5) / S - 0.5
    y = coords[:, None] + off[None, :] - c
    q = np.maximum(R * R - y * y, 0.0)
    return np.exp(-mu * 2 * np.sqrt(q)).mean(1)


def conventions():
    log('1. conventions')
    # horizontal rod, axis through row 100.0 (entry from the left border at row 0.5*200 = 100)
    cfg = straight_cfg()
    sc = render.Scene('conv_h', cfg)
    check(abs(-sc.base[1] - 100.0) < 1e-9, 'horizontal test rod placed on row %.6f' % -sc.base[1])
    obj = render.render_object(sc, 0, want={'T'})
    T = obj['T']
    mu = cfg['a_wall'] / (2 * sc.Ro)
    rows = np.arange(80, 121, dtype=float)
    fits = []
    for col in (40, 77, 133):
        prof = T[80:121, col].astype(float)
        r = least_squares(lambda p: rod_model(p, rows, mu) - prof, [99.3, sc.Ro * 0.9])
        fits.append(r.x)
        check(abs(r.x[0] - 100.0) < 0.005 and abs(r.x[1] - sc.Ro) < 0.005,
              'col %d: fitted axis row %.4f (truth 100), radius %.4f (truth %.4f), rms %.1e'
              % (col, r.x[0], r.x[1], sc.Ro, np.sqrt((r.fun ** 2).mean())))
    alt = [np.sqrt(((rod_model([c, sc.Ro], rows, mu) - T[80:121, 77]) ** 2).mean())
           for c in (99.5, 100.0, 100.5)]
    check(alt[1] < 0.05 * min(alt[0], alt[2]),
          'pixel-centre convention: rms misfit with the axis at row 99.5 / 100.0 / 100.5 = '
          '%.2e / %.2e / %.2e' % tuple(alt))
    # vertical rod entering from the bottom, axis on col 80.0
    cfg = straight_cfg(W=161, H=200, heading=90.0, entry='bottom', anchor=(0.5, 0.0))
    sc = render.Scene('conv_v', cfg)
    check(abs(sc.base[0] - 80.0) < 1e-9 and abs(sc.base[1] + 199.5) < 1e-9,
          'vertical test rod base at (col %.3f, row %.3f) = bottom outer pixel edge'
          % (sc.base[0], -sc.base[1]))
    T = render.render_object(sc, 0, want={'T'})['T']
    cols = np.arange(60, 101, dtype=float)
    for row in (190, 150, 120):
        prof = T[row, 60:101].astype(float)
        r = least_squares(lambda p: rod_model(p, cols, mu) - prof, [80.4, sc.Ro * 0.9])
        check(abs(r.x[0] - 80.0) < 0.005 and abs(r.x[1] - sc.Ro) < 0.005,
              'row %d: fitted axis col %.4f (truth 80), radius %.4f' % (row, r.x[0], r.x[1]))
    # the flat end of the horizontal rod: coverage 50 % at the truth tip
    cfg = straight_cfg()
    sc = render.Scene('conv_h', cfg)
    IN = render.render_object(sc, 0, want={'IN'})['IN']
    t = np.linspace(sc.L[0] - 8, sc.L[0] + 8, 321) - 0.5
    p = sample(IN, t, np.full_like(t, 100.0))
    tip_col = sc.base[0] + sc.L[0]
    e = crossing_from_outside(t, p, 0.5)[1]
    check(abs(e - tip_col) < 0.01, 'flat end face found at col %.4f, truth tip col %.4f'
          % (e, tip_col))
    # every look, straight tube at row 100.0: outer edges centred (incl. an eccentric lumen)
    # (a concentric lumen must give an exactly symmetric image; an eccentric one -- walls
    # thicker on one side, as these tubes have -- makes the interior asymmetric, and the
    # outer edges as found by this half-peak detector move by the amount reported)
    for look, extra in (('bf', {}), ('bf', dict(fill='air')), ('fluor', {}), ('phase', {}),
                        ('dic', dict(dic_angle=70.0)), ('dic', dict(dic_angle=-20.0)),
                        ('bf', dict(defocus_tip=[0.8, 4.0])),
                        ('bf', dict(psf_kind='disc', psf_disc=2.5)),
                        ('bf', dict(colour=True, tint=(0.7, 1.0, 1.4))),
                        ('bf', dict(ecc=0.15)), ('bf', dict(ecc=0.75, fill='air')),
                        ('fluor', dict(ecc=0.15)), ('phase', dict(ecc=0.15)),
                        ('dic', dict(dic_angle=70.0, ecc=0.15))):
        kw = dict(lumen=0.55, ecc=0.0, a_wall=0.12, na_g=0.22, psf=1.0, end='round', ss=4,
                  L_mm=3.4, W=240, profile=('steps', 0.0))
        kw.update(extra)
        kw['look'] = look
        cfg = straight_cfg(**kw)
        sc = render.Scene('conv_look', cfg)
        I, _ = render.linear_frame(sc, None, 0, clean=True)
        if I.ndim == 3:
            I = I.mean(2)
        d = np.linspace(-sc.Ro - 12, sc.Ro + 12, 481)
        offs = []
        for col in (30, 60, 90, 120):
            prof = sample(I, np.full_like(d, col), 100.0 + d)
            bg = np.median(np.r_[prof[:20], prof[-20:]])
            lo, hi = outer_edges(d, np.abs(prof - bg))
            offs.append((lo + hi) / 2)
        # DIC: absorption multiplies the relief, so its two lobes differ in height a little
        tol = (0.02 if look == 'dic' else 0.005) if cfg['ecc'] == 0 else 0.2
        check(max(abs(o) for o in offs) < tol,
              'look %-5s %-40s outer edges centred: offsets %s px'
              % (look, json.dumps(extra), ' '.join('%+.4f' % o for o in offs)))
    # the centroid estimator used on the scenes has a floor of its own: on a straight tube at a
    # fixed sub-pixel phase it reads the same offset whatever the renderer's super-sampling, so
    # what it reads is not a rendering error
    for y0 in (0.3, 0.9):
        vals = []
        for ss, s2 in ((3, 8), (8, 16)):
            render.REFINE_SS = s2
            cfg = straight_cfg(lumen=0.58, ecc=0.0, a_wall=0.12, na_g=0.22, psf=0.8, end='round',
                               ss=ss, D_px=10.0, L_mm=3.4, W=240, profile=('steps', 0.0),
                               anchor=(0.0, (100 + y0) / 200))
            cfg['look'] = 'bf'
            sc = render.Scene('conv_floor', cfg)
            I, _ = render.linear_frame(sc, None, 0, clean=True)
            segs, _, _ = sc.frame_segs(0)
            s = np.linspace(0, sc.L[0], int(sc.L[0] / 0.4) + 1)
            cx, cy = render.centreline(segs, s)
            tree = cKDTree(np.stack([cx, cy], 1))
            i = len(s) // 2
            vals.append(moment_offset(I, cx[i], cy[i], 0, 0, s[i], sc.Ro + 13, tree, s, cx,
                                      cy, np.zeros_like(s)))
        render.REFINE_SS = None
        check(abs(vals[0] - vals[1]) < 0.05,
              'estimator floor: straight 10 px tube on row %.1f, PSF 0.8 px: centroid offset %+.4f '
              'px at 3x3 (+8x8 at edges) samples/px, %+.4f px at 8x8 (+16x16): the rest is the '
              'sampling of the scenes\' renders (%.3f px)' % (100 + y0, *vals, abs(vals[0] - vals[1])))
    # sign conventions: base pointing right, +90 deg CCW -> tip up-right (row smaller)
    cfg = straight_cfg(bend=90.0, L_mm=2.0, H=301, W=301, anchor=(0.0, 0.7), profile=('steps', 1.0))
    sc = render.Scene('conv_sign', cfg)
    segs, tip, th = sc.frame_segs(0)
    R = sc.L[0] / (math.pi / 2)
    check(abs(tip[0] - (sc.base[0] + R)) < 1e-6 and abs(tip[1] - (sc.base[1] + R)) < 1e-6
          and abs(math.degrees(th) - 90) < 1e-9,
          '+90 deg from a base pointing right ends up-right: tip (col %.3f,row %.3f), '
          'heading %.3f deg' % (tip[0], -tip[1], math.degrees(th)))
    IN = render.render_object(sc, 0, want={'IN'})['IN']
    r_tip, c_tip = -tip[1], tip[0]
    check(IN[int(round(r_tip)) + 3, int(round(c_tip))] > 0.9 and
          IN[int(round(-sc.base[1] + R)) - 3, int(round(c_tip))] < 0.1,
          'rendered pixels follow the same geometry (body just below the tip, none mirrored)')


# =============================================================================== 2. scenes
def natural(s):
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r'(\d+)', s)]


def read_back(path):
    if os.path.isdir(path):
        fs = sorted(glob.glob(os.path.join(path, '*')), key=natural)
        return [cv2.imread(f, cv2.IMREAD_UNCHANGED) for f in fs], fs
    if path.endswith('.tif'):
        import tifffile
        a = tifffile.imread(path)
        return list(a), None
    cap = cv2.VideoCapture(path)
    out = []
    while True:
        ok, fr = cap.read()
        if not ok:
            break
        out.append(fr)
    return out, None


def as_grey(img):
    img = np.asarray(img)
    if img.ndim == 3:
        return img.astype(np.float64).mean(2)
    return img.astype(np.float64)


def moment_offset(img, X0, Y0, nx, ny, s0, ext, tree, cs, cx, cy, ck, sig_t=3.0):
    """Centroid, across the tube, of (I - bg)^2 over the pixels about the truth point (X0, Y0),
    weighted by a Gaussian in arc length (sigma sig_t).  Computed on the pixel grid itself
    (no interpolation): the image is smooth, so such sums are accurate to far below 0.01 px.
    d of each pixel is its signed distance to the truth centreline (left positive); each pixel
    is weighted by 1/(1 - kappa d), the area of a pixel in (arc length, d) coordinates, so the
    sum is an integral over d and s even where the tube bends."""
    H, W = img.shape
    r = ext + 3 * sig_t + 2
    c0, c1 = int(max(0, X0 - r)), int(min(W - 1, X0 + r))
    r0, r1 = int(max(0, -Y0 - r)), int(min(H - 1, -Y0 + r))
    rr, cc = np.mgrid[r0:r1 + 1, c0:c1 + 1]
    P = np.stack([cc.ravel().astype(float), -rr.ravel().astype(float)], 1)
    _, j = tree.query(P)
    j = np.clip(j, 1, len(cs) - 2)
    tx, ty = cx[j + 1] - cx[j - 1], cy[j + 1] - cy[j - 1]
    tn = np.hypot(tx, ty)
    tx, ty = tx / tn, ty / tn
    dx, dy = P[:, 0] - cx[j], P[:, 1] - cy[j]
    along = dx * tx + dy * ty
    d = -dx * ty + dy * tx
    t = cs[j] + along - s0
    v = img[rr.ravel(), cc.ravel()].astype(np.float64)
    band = np.abs(d) < ext
    far = band & (np.abs(d) > ext - 3) & (np.abs(t) < 2 * sig_t)
    bg = np.median(v[far]) if far.any() else np.median(v)
    jac = np.maximum(1 - ck[j] * d, 0.05)
    w = np.exp(-0.5 * (t / sig_t) ** 2) * (v - bg) ** 2 * smooth_cut(np.abs(d), ext) / jac
    return float((w * d).sum() / w.sum())


def smooth_cut(a, ext):
    """1 inside, smooth roll-off to 0 over the last 3 px before ext."""
    x = np.clip((ext - a) / 3.0, 0, 1)
    return x * x * (3 - 2 * x)


def independent_centreline(meta, k, step=0.01):
    """Integrate dtheta/ds = kappa(s) from the scene's settings, by small steps."""
    c = meta['settings']
    um = meta['um_per_px']
    N = meta['n_frames']
    p = render.profile_p(c['profile'], N)[k]
    L0 = c['L_mm'] * 1000 / um
    plug = c['plug_um'] / um
    Lb = (L0 - plug) * (1 + c['elong'] * p)
    Lb1 = (L0 - plug) * (1 + c['elong'])
    fr = np.array(c['fractions'], float)
    fr /= fr.sum()
    r = np.array(c['ratios'], float)
    krest = math.radians(c['rest']) / (L0 - plug)
    K1 = (math.radians(c['bend']) - krest * Lb1) / (r * fr * Lb1).sum()
    bounds = np.r_[0, np.cumsum(fr * Lb)]
    kap = krest + K1 * r * p
    L = Lb + plug
    n = int(L / step) + 1
    s = np.linspace(0, L, n)
    ds = s[1] - s[0]
    idx = np.clip(np.searchsorted(bounds, s, side='right') - 1, 0, len(r))
    kk = np.where(s < Lb, kap[np.minimum(idx, len(r) - 1)], 0.0)
    th0 = math.radians(c['heading'])
    theta = th0 + np.r_[0, np.cumsum(0.5 * (kk[1:] + kk[:-1]) * ds)]
    x = np.r_[0, np.cumsum(0.5 * (np.cos(theta[1:]) + np.cos(theta[:-1])) * ds)]
    y = np.r_[0, np.cumsum(0.5 * (np.sin(theta[1:]) + np.sin(theta[:-1])) * ds)]
    return s, x, y, math.degrees(theta[-1] - th0), L


def verify_scene(name):
    t0 = time.time()
    d = os.path.join(render.SCENE_DIR, name)
    meta = json.load(open(os.path.join(d, 'scene.json')))
    tr = pd.read_csv(os.path.join(d, 'truth_tracks.csv'))
    tcl = pd.read_csv(os.path.join(d, 'truth_centrelines.csv'))
    sc, bgd, ov = render.load_scene(name)
    # concentric-lumen twin (for DIC also without absorption: absorption times relief makes
    # (I - bg)^2 lopsided by construction)
    sc0 = render.Scene(name, dict(sc.c, ecc=0.0, **({'a_wall': 0.0} if sc.c['look'] == 'dic' else {})))
    um = sc.um
    log('%s  (%s, %dx%d, %d frames)' % (name, meta['input'], sc.W, sc.H, sc.N))
    ok_all = True
    frames = sorted({0, sc.N // 2, sc.N - 1})
    # ---- e. truth files
    errs_b, errs_l, errs_i, gaps, ends = [], [], [], [], []
    for k in range(sc.N):
        g = tcl[tcl.frame == k]
        x, y = g.x_um.values / um, g.y_um.values / um
        s = g.s_um.values / um
        t = tr[tr.frame == k].iloc[0]
        dx, dy = np.diff(x), np.diff(y)
        seg = np.hypot(dx, dy)
        gaps.append(seg.max())
        ang = np.unwrap(np.arctan2(dy, dx))
        a0 = ang[0] - 0.5 * (ang[1] - ang[0]) * seg[0] / seg[1]
        a1 = ang[-1] + 0.5 * (ang[-1] - ang[-2]) * seg[-1] / seg[-2]
        errs_b.append(math.degrees(a1 - a0) - t.bend_angle_deg)
        errs_l.append(seg.sum() - t.length_um / um)
        ends.append(max(math.hypot(x[0] - t.base_x_um / um, y[0] - t.base_y_um / um),
                        math.hypot(x[-1] - t.tip_x_um / um, y[-1] - t.tip_y_um / um),
                        abs(s[-1] - t.length_um / um)))
        if k in frames or k % 7 == 0:
            si, xi, yi, bend_i, Li = independent_centreline(meta, k)
            xi = xi + t.base_x_um / um
            yi = yi + t.base_y_um / um
            P = np.stack([x, y], 1)
            Q = np.stack([np.interp(s, si, xi), np.interp(s, si, yi)], 1)
            errs_i.append(max(np.hypot(*(P - Q).T).max(), abs(bend_i - t.bend_angle_deg) / 10,
                              abs(Li - t.length_um / um)))
    ok_all &= check(max(np.abs(errs_b)) < 0.02, 'bend = integral of the polyline\'s curvature: '
                    'max |diff| %.4f deg over %d frames' % (max(np.abs(errs_b)), sc.N))
    ok_all &= check(max(np.abs(errs_l)) < 1e-3, 'length = polyline length: max |diff| %.2e px'
                    % max(np.abs(errs_l)))
    ok_all &= check(max(gaps) <= 0.5 and max(ends) < 1e-3,
                    'point spacing <= %.3f px; first/last point = base/tip (%.1e px)'
                    % (max(gaps), max(ends)))
    ok_all &= check(max(errs_i) < 0.01, 'independent integration of curvature from settings: '
                    'max deviation %.4f px (bend diff/10 deg, length px)' % max(errs_i))
    ok_all &= check(len(tr) == meta['n_frames'] == sc.N and
                    np.allclose(tr.time_s.values, np.arange(sc.N) / meta['fps']),
                    'n_frames %d, truth rows %d, time_s = frame/fps' % (meta['n_frames'], len(tr)))
    # ---- tube inside the image
    marg = []
    for k in range(sc.N):
        g = tcl[tcl.frame == k]
        col, row = g.x_um.values / um, -g.y_um.values / um
        s = g.s_um.values / um
        if sc.c['entry']:
            lean = abs(math.sin(sc.theta)) if sc.c['entry'] in ('top', 'bottom') else abs(math.cos(sc.theta))
            keep = s > (3 * sc.Ro + 4) / max(lean, 0.15)
            col, row = col[keep], row[keep]
        marg.append(min(col.min(), row.min(), sc.W - 1 - col.max(), sc.H - 1 - row.max()) - sc.Ro)
    ok_all &= check(min(marg) >= 3, 'tube inside the image: min clearance of its edge %.1f px'
                    % min(marg))
    # ---- a-d per frame, clean renders
    geo_off, geo_w, opt_off, tip_err, base_err, edge_off, where = [], [], [], [], [], [], []
    rm = sc.rmax()
    for k in frames:
        segs, tip, th_tip = sc.frame_segs(k)
        L = sc.L[k]
        I, _ = render.linear_frame(sc, bgd, k, clean=True)
        Ig = I.mean(2) if I.ndim == 3 else I
        I0, _ = render.linear_frame(sc0, bgd, k, clean=True)     # concentric-lumen twin
        Ig0 = I0.mean(2) if I0.ndim == 3 else I0
        g = tcl[tcl.frame == k]
        cx, cy = g.x_um.values / um, g.y_um.values / um
        cs = g.s_um.values / um
        tree = cKDTree(np.stack([cx, cy], 1))
        bounds = np.cumsum([0.0] + [ln for _, ln in sc.secs[k]])
        kaps = np.array([kk for kk, _ in sc.secs[k]])
        ck = kaps[np.clip(np.searchsorted(bounds, cs, side='right') - 1, 0, len(kaps) - 1)]
        sig = sc.sigma_max
        ss = np.arange(max(2.5 * rm, 3 * sc.Ro) + 2, L - 3 * sc.Ro, max(4.0, sc.Ro))
        joints = []
        if sc.c['ro_steps']:
            fr = np.array(sc.c['fractions'], float)
            joints = list(np.cumsum(fr / fr.sum())[:-1] * (L - sc.plug))
        for s0 in ss:
            if any(abs(s0 - j) < 1.5 * sc.Ro for j in joints):
                continue
            X, Y = render.centreline(segs, np.array([s0]))
            i = np.searchsorted(cs, s0)
            i = min(max(i, 1), len(cs) - 1)
            tx, ty = cx[i] - cx[i - 1], cy[i] - cy[i - 1]
            n = math.hypot(tx, ty)
            nx, ny = -ty / n, tx / n
            ro = sc.radii(np.array([s0]), k)[0][0]
            ext = ro + 6 * sig + 8 + (ro * 0.8 if sc.c['look'] == 'phase' else 0)
            dd = np.linspace(-ext, ext, int(2 * ext / 0.02) + 1)
            px, py = X[0] + dd * nx, Y[0] + dd * ny
            # clear of other parts of the tube, of the holder and of the image border
            near = tree.query_ball_point(np.stack([px, py], 1), ro + 3 * sig + 4)
            if any(abs(cs[j] - s0) > 2 * ext + 2 for lst in near for j in lst):
                continue
            if sc.holder != 'none':
                c, s_ = math.cos(sc.theta), math.sin(sc.theta)
                u = (px - sc.base[0]) * c + (py - sc.base[1]) * s_
                v = -(px - sc.base[0]) * s_ + (py - sc.base[1]) * c
                if ((u < 3 * sig + 4) & (np.abs(v) < rm + 3 * sig + 4)).any():
                    continue
            pc, pr = px, -py
            if pc.min() < 1 or pr.min() < 1 or pc.max() > sc.W - 2 or pr.max() > sc.H - 2:
                continue
            # the whole window of the moment sums (+-3 sigma_t along) must be clear too
            rx = ext + 11.0
            if any(abs(cs[j] - s0) > 1.6 * rx for j in tree.query_ball_point((X[0], Y[0]), rx)):
                continue
            if sc.holder != 'none':
                du, dv = X[0] - sc.base[0], Y[0] - sc.base[1]
                u0 = du * c + dv * s_
                v0 = -du * s_ + dv * c
                if math.hypot(max(u0, 0.0), max(abs(v0) - rm, 0.0)) < rx:
                    continue
            if X[0] - rx < 0 or -Y[0] - rx < 0 or X[0] + rx > sc.W - 1 or -Y[0] + rx > sc.H - 1:
                continue
            cv_ = at_points(sc, k, pc, pr)['IN']
            lo, hi = crossing_from_outside(dd, cv_, 0.5)
            geo_off.append((lo + hi) / 2)
            geo_w.append((hi - lo) / 2 - ro)
            opt_off.append([moment_offset(im, X[0], Y[0], nx, ny, s0, ext, tree, cs, cx, cy, ck)
                            for im in (Ig0, Ig)])
            prof = sample(Ig, pc, pr)
            bg = np.median(np.r_[prof[:10], prof[-10:]])
            lo, hi = outer_edges(dd, np.abs(prof - bg))
            thin = -sc.bend_sign                 # the side of the thin wall (+1 = left)
            edge_off.append(thin * (lo + hi) / 2)
            where.append((k, s0))
        # tip: coverage along the tip tangent
        tx, ty = math.cos(th_tip), math.sin(th_tip)
        dd = np.linspace(-2 * sc.Ro, 3, 1 + int((2 * sc.Ro + 3) / 0.005))
        cv_ = at_points(sc, k, tip[0] + dd * tx, -(tip[1] + dd * ty), s_from=L - 3 * sc.Ro)['IN']
        e = crossing_from_outside(dd, cv_, 0.5)[1]
        # a round cap's outline is a circle: area averaging puts its 50 % level inside by
        # about 1/(24 R) px; flat faces have no bias
        tip_err.append(e)
        # base
        if sc.holder == 'none':
            bx, by = sc.base
            e = {'left': bx + 0.5, 'right': bx - (sc.W - 0.5), 'top': -by + 0.5,
                 'bottom': -by - (sc.H - 0.5)}[sc.c['entry']]
            base_err.append(e)
        else:
            c, s_ = math.cos(sc.theta), math.sin(sc.theta)
            if sc.holder == 'glass':
                offs = [(sc.Rpi + sc.Rpo) / 2, -(sc.Rpi + sc.Rpo) / 2]
            else:
                offs = [(sc.H2 + sc.Ro) / 2 + 1, -(sc.H1 + sc.Ro) / 2 - 1]
            uu = np.linspace(-2 * sc.Ro, 2 * sc.Ro, 1 + int(4 * sc.Ro / 0.005))
            for v in offs:
                px = sc.base[0] + uu * c - v * s_
                py = sc.base[1] + uu * s_ + v * c
                pc, pr = px, -py
                gi = at_points(sc, k, pc, pr)['GI']
                e = crossing_from_outside(uu, gi, 0.5)[1]
                base_err.append(e)
    geo_off, geo_w, opt_off = map(np.asarray, (geo_off, geo_w, opt_off))
    where = list(where)
    nprof = len(geo_off)
    ok_all &= check(nprof >= 10, '%d cross-sections measured on frames %s' % (nprof, frames))
    if nprof:
        tq = 0.012                               # the profiles' step is 0.05 px / 0.02 px
        ok_all &= check(np.abs(geo_off).max() < tq and np.abs(geo_w).max() < 2 * tq,
                        'body (renderer evaluated at exact points): side edges centred on the '
                        'truth (max |offset| %.4f px), half-width = ro (max |err| %.4f px)'
                        % (np.abs(geo_off).max(), np.abs(geo_w).max()))
        o0, o1 = np.abs(opt_off[:, 0]), np.abs(opt_off[:, 1])
        im = int(np.argmax(o0))
        # (the centroid of a squared, sampled profile has an aliasing floor of ~0.07 px at a
        # 0.8 px PSF -- it does not change with the renderer's super-sampling)
        ok_all &= check(np.median(o0) < 0.04 and np.percentile(o0, 95) < 0.1 and o0.max() < 0.2,
                        'clean optical image (%s), concentric-lumen twin: centroid of (I-bg)^2 '
                        'across the tube on the truth: |offset| median %.4f, 95%% %.4f, max %.4f px '
                        '(frame %d, s %.0f px)'
                        % (sc.c['look'], np.median(o0), np.percentile(o0, 95), o0.max(),
                           where[im][0], where[im][1]))
        eo = np.asarray(edge_off)
        eo = eo[np.isfinite(eo)]
        log('  info outer edges of the scene itself (half peak of |I-bg| from outside): midpoint '
            'offset towards the thin wall: median %+.4f px, 10-90%% %+.3f..%+.3f px'
            % (np.median(eo), np.percentile(eo, 10), np.percentile(eo, 90)))
        log('  info the scene itself (lumen offset %.2f px: walls thicker on one side): median '
            '|offset| %.4f px, max %.4f px (an asymmetric interior moves this centroid)'
            % (sc.ecc, np.median(o1), o1.max()))
    tip_err = np.asarray(tip_err)
    tol = 0.012
    ok_all &= check(np.all(np.abs(tip_err) < tol),
                    'tip: body coverage ends at the truth tip (%s end): errors %s px'
                    % ('round' if sc.round else 'flat', ' '.join('%+.4f' % e for e in tip_err)))
    base_err = np.asarray(base_err, float)
    ok_all &= check(len(base_err) > 0 and np.all(np.abs(base_err) < 0.012),
                    'base: %s at the truth base: errors %s px'
                    % ({'none': 'on the border\'s outer pixel edge', 'glass': 'pipette end face',
                        'clamp': 'clamp front face'}[sc.holder],
                       ' '.join('%+.4f' % e for e in base_err)))
    # ---- f. files: read back, order, match a re-render
    fr_read, names = read_back(os.path.join(d, meta['input']))
    ok_all &= check(len(fr_read) == sc.N, 'read back %d frames from %s' % (len(fr_read), meta['input']))
    if names is not None:
        log('         folder order (natural sort): %s' % ', '.join(os.path.basename(n) for n in names[:3] + names[8:11]))
    diffs = []
    for k in frames:
        ref, _, _ = render.final_frame(sc, bgd, k, ov)
        got = fr_read[k]
        if got.ndim == 3 and ref.ndim == 3:
            got = got[..., ::-1]                      # BGR from cv2 -> RGB
        if got.ndim == 3 and ref.ndim == 2:
            got = got[..., 0]
        a, b = as_grey(got), as_grey(ref)
        if a.shape != b.shape:
            diffs.append((k, np.inf, np.inf))
            continue
        other = k + 1 if k + 1 < sc.N else k - 1
        alt = as_grey(fr_read[other][..., ::-1] if fr_read[other].ndim == 3 and ref.ndim == 3 else
                      (fr_read[other][..., 0] if fr_read[other].ndim == 3 else fr_read[other]))
        rng = float(b.max() - b.min()) or 1.0
        diffs.append((k, np.abs(a - b).mean() / rng, np.abs(alt - b).mean() / rng))
    lossless = sc.c['fmt'] in ('avi_ffv1', 'avi_y800', 'avi_hfyu', 'mkv', 'tif8', 'tif16', 'tifrgb',
                               'bmp', 'png16', 'png8')
    tol = 1e-9 if lossless else 0.03
    ok_all &= check(all(dk <= tol and (dk < da or sc.N == 1 or da == 0) for _, dk, da in diffs),
                    'decoded frames = re-rendered frames (%s): mean |diff|/range %s (vs the '
                    'neighbour frame %s)' % ('lossless' if lossless else 'lossy',
                                             ' '.join('%.4f' % dk for _, dk, _ in diffs),
                                             ' '.join('%.4f' % da for _, _, da in diffs)))
    log('         (%.1f s)' % (time.time() - t0))
    return ok_all


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--only', nargs='*')
    a = ap.parse_args()
    t0 = time.time()
    conventions()
    log()
    log('2. scenes')
    names = sorted(n for n in os.listdir(render.SCENE_DIR)
                   if os.path.exists(os.path.join(render.SCENE_DIR, n, 'scene.json')))
    if a.only:
        names = [n for n in names if n in a.only]
    bad = []
    for n in names:
        if not verify_scene(n):
            bad.append(n)
    log()
    log('%d checks failed%s; %d scenes, %.0f s'
        % (len(FAILS), (' (scenes: ' + ', '.join(bad) + ')') if bad else '', len(names),
           time.time() - t0))
    if not a.only:
        with open(os.path.join(HERE, 'verify_report.txt'), 'w') as f:
            f.write('\n'.join(LINES) + '\n')
    sys.exit(1 if FAILS else 0)


if __name__ == '__main__':
    main()

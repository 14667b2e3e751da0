#!/usr/bin/env python
"""alien8 renderer: synthetic microscope videos of a pneumatic PDMS microtube, with exact truth.

    python render.py [-j 2] [--only NAME ...] [--list] [--plan] [--check]

Written from the subject's physics, apart from the tracker and the other sets' renderers.
Every scene goes to scenes/<name>/: the frames, scene.json, truth_tracks.csv,
truth_centrelines.csv. Deterministic: every random number comes from a seed made from the
scene's name (sha256) and the frame index.

Geometry is in pixels, in a math frame X = col, Y = -row (y up); x_um = X*um, y_um = Y*um.
"""
import argparse
import hashlib
import json
import math
import os
import re
import shutil
import sys
import time
from multiprocessing import Pool

import cv2
import numpy as np
import tifffile
from PIL import Image

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES_DIR = os.path.join(HERE, 'scenes')
PAD = 24            # canvas margin (px) on every side: the PSF and border bases blur correctly
N_WATER, N_AIR, N_PDMS, N_GLASS = 1.333, 1.000, 1.412, 1.474
# per-sample accumulators: L = -absorbance, R = log of the light the objective still accepts after
# refraction, Ad = dye absorbance (scaled per colour channel), O = log transmission of opaque
# occluders, P = optical path difference to the medium (px), E = fluorescence emission
ACC = ('L', 'R', 'Ad', 'O', 'P', 'E')


def seed_of(name, *extra):
    h = hashlib.sha256(('alien8|%s|%s' % (name, '|'.join(map(str, extra)))).encode()).digest()
    return int.from_bytes(h[:8], 'little')


# ----------------------------------------------------------------------------- sampling
def lattice(S):
    """S*S point-symmetric rank-1 lattice offsets in a pixel (distinct rows and columns)."""
    N = S * S
    g = {4: 1, 9: 2, 16: 5, 25: 7, 36: 13, 49: 19}[N]
    c = next(c for c in range(N) if (2 * c - (g - 1)) % N == 0)
    k = np.arange(N)
    ox = (k + 0.5) / N - 0.5
    oy = ((k * g + c) % N + 0.5) / N - 0.5
    pts = set(zip(np.round(ox, 9), np.round(oy, 9)))
    assert all((round(-a, 9), round(-b, 9)) in pts for a, b in pts), 'lattice not symmetric'
    return ox, oy


# ----------------------------------------------------------------------------- curves
def _local(u, k):
    """Offset (along, normal) of a point at arc length u on an arc of curvature k (stable k->0)."""
    x = u * np.sinc(k * u / np.pi)
    y = u * (k * u / 2.0) * np.sinc(k * u / (2 * np.pi)) ** 2
    return x, y


class Curve:
    """A chain of pieces (straight or circular), each at most max_len long and 90 deg."""

    def __init__(self, P0, th0, lengths, kappas, s0=0.0, max_len=64.0):
        rows = []
        s, P, th = float(s0), np.array(P0, float), float(th0)
        for l, k in zip(lengths, kappas):
            if l <= 0:
                continue
            n = max(1, int(math.ceil(abs(k) * l / (math.pi / 2) - 1e-9)),
                    int(math.ceil(l / max_len - 1e-9)))
            lj = l / n
            for _ in range(n):
                rows.append((s, lj, P[0], P[1], th, k))
                a, b = _local(lj, k)
                P = P + np.array([a * math.cos(th) - b * math.sin(th),
                                  a * math.sin(th) + b * math.cos(th)])
                th += k * lj
                s += lj
        self.pc = np.array(rows, float)
        self.s0, self.s1 = float(s0), s
        self.P1, self.th1 = P, th

    def _idx(self, s):
        return np.clip(np.searchsorted(self.pc[:, 0], s, 'right') - 1, 0, len(self.pc) - 1)

    def points(self, s):
        s = np.asarray(s, float)
        p = self.pc[self._idx(s)]
        u = s - p[..., 0]
        a, b = _local(u, p[..., 5])
        c, sn = np.cos(p[..., 4]), np.sin(p[..., 4])
        return np.stack([p[..., 2] + a * c - b * sn, p[..., 3] + a * sn + b * c], -1)

    def heading(self, s):
        s = np.asarray(s, float)
        p = self.pc[self._idx(s)]
        return p[..., 4] + p[..., 5] * (s - p[..., 0])


def foot(pc, X, Y):
    """Arc length u along piece pc and signed normal offset d (left +) of points (X, Y)."""
    _, l, Px, Py, th, k = pc
    dx, dy = X - Px, Y - Py
    c, s = math.cos(th), math.sin(th)
    a = dx * c + dy * s
    b = -dx * s + dy * c
    if k == 0.0:
        return a, b
    ka, kb = k * a, 1.0 - k * b
    u = np.arctan2(ka, kb) / k
    d = (2 * b - k * (a * a + b * b)) / (1.0 + np.sqrt(ka * ka + kb * kb))
    return u, d


# ----------------------------------------------------------------------------- optics helpers
def deviation(sin_i, n_out, n_in):
    """Total deviation (rad, + = toward the circle's centre) of a ray crossing a circle of index
    n_in in a medium n_out at impact parameter sin_i (fraction of its radius); NaN on TIR."""
    i = np.arcsin(np.clip(sin_i, 0, 1))
    st = sin_i * (n_out / n_in)
    with np.errstate(invalid='ignore'):
        r = np.where(st <= 1.0, np.arcsin(np.clip(st, 0, 1)), np.nan)
    return 2.0 * (i - r)


def accepted(delta, a_c, a_o):
    """Fraction of an illumination cone (half-angle a_c) deviated by delta that the objective
    (half-angle a_o) accepts (overlap of two discs / the first one's area), relative to the
    background's (delta = 0). 0 where delta is NaN (total internal reflection)."""
    dl = np.abs(np.nan_to_num(delta, nan=10.0))
    a, b = a_c, a_o
    out = np.zeros_like(dl)
    full = dl <= abs(b - a)
    out[full] = min(a, b) ** 2 / a ** 2
    part = (~full) & (dl < a + b)
    if part.any():
        d = dl[part]
        c1 = np.clip((d * d + a * a - b * b) / (2 * d * a), -1, 1)
        c2 = np.clip((d * d + b * b - a * a) / (2 * d * b), -1, 1)
        k = np.sqrt(np.clip((-d + a + b) * (d + a - b) * (d - a + b) * (d + a + b), 0, None))
        out[part] = (a * a * np.arccos(c1) + b * b * np.arccos(c2) - 0.5 * k) / (math.pi * a * a)
    return out / (min(a, b) ** 2 / a ** 2)     # relative to the undeviated background


# ----------------------------------------------------------------------------- bodies
class Body:
    """A swept body along a curve: circular cross-section r(s), optional lumen (ri(s), offset
    e(s) along the left normal), flat ends at s_lo / s_hi unless r(s) closes itself (a cap).
    kind: 'tube' (round), 'slab' (flat jaw: opaque where |d| < r), 'sphere' (a bubble)."""

    def __init__(self, curve, s_lo, s_hi, radius, lumen=None, kind='tube', n_b=N_PDMS,
                 n_l=N_AIR, mu=0.0, mu_l=0.0, mu_dye=0.0, emis=0.0, occ=1.0, face_scatter=0.0,
                 face_w=0.8, name='', cap=None):
        self.curve, self.s_lo, self.s_hi = curve, s_lo, s_hi
        self.cap = cap          # (s of the cap's centre, its outer radius, its lumen radius)
        self.radius, self.lumen, self.kind = radius, lumen, kind
        self.n_b, self.n_l, self.mu, self.mu_l, self.mu_dye = n_b, n_l, mu, mu_l, mu_dye
        self.emis, self.occ, self.face_scatter, self.face_w = emis, occ, face_scatter, face_w
        self.name = name
        self.rmax = float(np.max(radius(np.linspace(s_lo, s_hi, 257))))


class Sphere:
    def __init__(self, cx, cy, R, n_in=N_AIR, name='bubble'):
        self.cx, self.cy, self.R, self.n_in, self.name = cx, cy, R, n_in, name


def body_layers(body, opt, lat, shape):
    """Per-sample layer quantities of one body. Returns a list of (flat pixel ids, dict acc)."""
    Hc, Wc = shape
    ox, oy = lat
    out = []
    a_c, a_o, n_m = opt['a_c'], opt['a_o'], opt['n_m']
    if isinstance(body, Sphere):
        r0 = int(math.floor(-body.cy - body.R - 1)) + PAD
        r1 = int(math.ceil(-body.cy + body.R + 1)) + PAD
        c0 = int(math.floor(body.cx - body.R - 1)) + PAD
        c1 = int(math.ceil(body.cx + body.R + 1)) + PAD
        r0, c0, r1, c1 = max(r0, 0), max(c0, 0), min(r1, Hc - 1), min(c1, Wc - 1)
        if r1 < r0 or c1 < c0:
            return out
        rr, cc = np.mgrid[r0:r1 + 1, c0:c1 + 1]
        rr, cc = rr.ravel(), cc.ravel()
        X = (cc - PAD)[:, None] + ox[None, :]
        Y = -((rr - PAD)[:, None] + oy[None, :])
        rho = np.hypot(X - body.cx, Y - body.cy)
        inside = rho < body.R
        keep = inside.any(1)
        if not keep.any():
            return out
        rho, inside = rho[keep], inside[keep]
        sin_i = np.where(inside, rho / body.R, 0)
        dev = deviation(sin_i, n_m, body.n_in)
        fr = accepted(dev, a_c, a_o)
        Rf = np.where(inside, np.log(np.maximum(fr, 1e-5)), 0.0)
        chord = np.where(inside, 2 * np.sqrt(np.maximum(body.R ** 2 - rho ** 2, 0)), 0)
        acc = dict(R=Rf, P=(body.n_in - n_m) * chord)
        out.append(((rr * Wc + cc)[keep], acc))
        return out
    cv = body.curve
    for pc in cv.pc:
        s0, l = pc[0], pc[1]
        if s0 + l < body.s_lo - 1 or s0 > body.s_hi + 1:
            continue
        uu = np.linspace(0, l, 9)
        pts = cv.points(np.clip(s0 + uu, cv.s0, cv.s1 - 1e-9))
        m = body.rmax + 2.0
        c0 = int(math.floor(pts[:, 0].min() - m)) + PAD
        c1 = int(math.ceil(pts[:, 0].max() + m)) + PAD
        r0 = int(math.floor(-pts[:, 1].max() - m)) + PAD
        r1 = int(math.ceil(-pts[:, 1].min() + m)) + PAD
        r0, c0, r1, c1 = max(r0, 0), max(c0, 0), min(r1, Hc - 1), min(c1, Wc - 1)
        if r1 < r0 or c1 < c0:
            continue
        rr, cc = np.mgrid[r0:r1 + 1, c0:c1 + 1]
        rr, cc = rr.ravel(), cc.ravel()
        Xp, Yp = (cc - PAD).astype(float), -(rr - PAD).astype(float)
        u, d = foot(pc, Xp, Yp)
        sp = s0 + u
        pre = ((u > -0.8) & (u < l + 0.8) & (sp > body.s_lo - 0.8) & (sp < body.s_hi + 0.8)
               & (np.abs(d) < body.rmax + 0.8))
        if not pre.any():
            continue
        rr, cc = rr[pre], cc[pre]
        X = (cc - PAD)[:, None] + ox[None, :]
        Y = -((rr - PAD)[:, None] + oy[None, :])
        u, d = foot(pc, X, Y)
        s = s0 + u
        last = s0 + l >= cv.s1 - 1e-9
        valid = (u >= 0) & ((u < l) | (last & (u <= l))) & (s >= body.s_lo) & (s <= body.s_hi)
        sc = np.clip(s, body.s_lo, body.s_hi)
        r = body.radius(sc)
        ins = valid & (np.abs(d) < r)
        keep = ins.any(1)
        if not keep.any():
            continue
        rr, cc, d, sc, r, ins = rr[keep], cc[keep], d[keep], sc[keep], r[keep], ins[keep]
        if body.kind == 'slab':
            acc = dict(O=np.where(ins, math.log(max(body.occ, 1e-4)), 0.0))
            out.append((rr * Wc + cc, acc))
            continue
        co = np.where(ins, 2 * np.sqrt(np.maximum(r * r - d * d, 0)), 0.0)
        # refraction: a ray at (s, d) meets the side wall as a cylinder (impact |d| / r) and the
        # round cap (s beyond its centre) as a sphere (impact sqrt(ds^2 + d^2) / Rc); the
        # deviation is a vector in the image plane (components across and along the tube)
        if body.cap is not None:
            cs, cR, cRl = body.cap
            inc = ins & (sc > cs)
            ds = np.where(inc, sc - cs, 0.0)
        else:
            inc, ds, cR, cRl = np.zeros_like(ins), 0.0 * d, 1.0, 1.0
        rho = np.hypot(ds, d)
        sin_o = np.where(ins, rho / np.maximum(np.where(inc, cR, r), 1e-9), 0)
        mag = deviation(np.minimum(sin_o, 1.0), n_m, body.n_b)
        with np.errstate(invalid='ignore', divide='ignore'):
            ud, us = np.where(rho > 0, d / rho, 0.0), np.where(rho > 0, ds / rho, 0.0)
        dev_d, dev_s = -mag * ud, -mag * us
        cl = np.zeros_like(co)
        if body.lumen is not None:
            ri, e = body.lumen(sc)
            dl = d - e
            inl = ins & (np.abs(dl) < ri)
            cl = np.where(inl, 2 * np.sqrt(np.maximum(ri * ri - dl * dl, 0)), 0.0)
            rl = np.hypot(ds, dl)
            sin_l = np.where(inl, rl / np.maximum(np.where(inc, cRl, ri), 1e-9), 0)
            ml = np.where(inl, deviation(np.minimum(sin_l, 1.0), body.n_b, body.n_l), 0.0)
            with np.errstate(invalid='ignore', divide='ignore'):
                dev_d = dev_d - ml * np.where(rl > 0, dl / rl, 0.0)
                dev_s = dev_s - ml * np.where(rl > 0, ds / rl, 0.0)
        dev = np.hypot(dev_d, dev_s)
        wall = co - cl
        fr = accepted(dev, a_c, a_o)
        Rf = np.where(ins, np.log(np.maximum(fr, 1e-5)), 0.0)
        L = -body.mu * wall - body.mu_l * cl
        if body.face_scatter > 0:   # the rough cut face scatters light out of the aperture
            Rf = Rf + np.where(ins, np.log(1 - body.face_scatter
                                           * np.exp(-0.5 * ((sc - body.s_lo) / body.face_w) ** 2)), 0)
        acc = dict(L=L, R=Rf,
                   P=np.where(ins, (body.n_b - n_m) * co + (body.n_l - body.n_b) * cl, 0.0))
        if body.mu_dye:
            acc['Ad'] = body.mu_dye * wall
        if body.emis:
            acc['E'] = body.emis * wall
        if body.occ < 1:
            acc['O'] = np.where(ins, math.log(max(body.occ, 1e-4)), 0.0)
        out.append((rr * Wc + cc, acc))
    return out


class Layered:
    """Sparse per-sample accumulators over a set of canvas pixels."""

    def __init__(self, parts, ns):
        if parts:
            ids = np.unique(np.concatenate([p[0] for p in parts]))
        else:
            ids = np.zeros(0, np.int64)
        self.ids = ids
        self.acc = {k: np.zeros((len(ids), ns)) for k in ACC}
        for pid, a in parts:
            pos = np.searchsorted(ids, pid)
            for k, v in a.items():
                self.acc[k][pos] += v

    def merge_static(self, st):
        """Add a static Layered (holder, bubbles, fibres) per sample at the pixels both hold."""
        if len(st.ids) == 0:
            return
        pos = np.clip(np.searchsorted(st.ids, self.ids), 0, len(st.ids) - 1)
        hit = st.ids[pos] == self.ids
        for k in ACC:
            self.acc[k][hit] += st.acc[k][pos[hit]]

    def pixel_values(self, kdye, refraction=True):
        """Per pixel: transmission per channel, emission (occluded), optical path."""
        a = self.acc
        base = a['L'] + a['O'] + (a['R'] if refraction else 0.0)
        T = [np.exp(base - k * a['Ad']).mean(1) for k in kdye]
        E = (a['E'] * np.exp(a['O'])).mean(1)
        P = a['P'].mean(1)
        return T, E, P


# ----------------------------------------------------------------------------- scene geometry
def tube_sections(sc):
    """Section lengths (px) and per-frame curvatures (1/px) -> list of kappa arrays per frame."""
    tb = sc['tube']
    Lpx = tb['L_um'] / sc['um']
    fr = np.array([s['frac'] for s in tb['sections']], float)
    fr = fr / fr.sum()
    lens = fr * Lpx
    ratio = np.array([s.get('ratio', 1.0) for s in tb['sections']], float)
    rest = np.array([s.get('rest_deg', 0.0) for s in tb['sections']], float)  # rest bend per sec
    k_rest = np.radians(rest) / lens
    B_rest = np.degrees((k_rest * lens).sum())
    kap = []
    for B in sc['bends']:
        c = math.radians(B - B_rest) / float((ratio * lens).sum())
        kap.append(k_rest + ratio * c)
    return lens, kap


def radii(sc):
    tb = sc['tube']
    ro0 = tb['od_um'] / 2 / sc['um']
    ri = ro0 * tb.get('id_frac', 0.6)
    ros = np.array([ro0 * s.get('od_scale', 1.0) for s in tb['sections']])
    ecc = np.array([s.get('ecc', tb.get('ecc', 0.2)) for s in tb['sections']])
    e = ecc * (ros - ri)          # offset of the lumen's centre toward the thin wall (px)
    return ro0, ri, ros, e


def frame_offsets(sc):
    """Per-frame stage/camera offset of the whole specimen, in image px (dcol, drow)."""
    n = sc['n']
    off = np.zeros((n, 2))
    fld = sc.get('field', {})
    if 'drift' in fld:
        vx, vy = fld['drift']
        off += np.outer(np.arange(n), [vx, vy])
    if 'shake' in fld:
        rng = np.random.default_rng(seed_of(sc['name'], 'shake'))
        amp = fld['shake']
        j = rng.normal(0, amp, (n, 2))
        j[0] = 0
        off += j
    return off


def tube_curve(sc, f, off=(0.0, 0.0)):
    lens, kap = sc['_lens'], sc['_kap'][f]
    bx, by = sc['base']
    X0, Y0 = bx + off[0], -(by + off[1])
    th0 = math.radians(sc['heading'])
    back = sc['_back']
    P0 = (X0 - back * math.cos(th0), Y0 - back * math.sin(th0))
    return Curve(P0, th0, [back] + list(lens), [0.0] + list(kap), s0=-back)


def make_tube_body(sc, curve):
    tb = sc['tube']
    ro0, ri, ros, e = radii(sc)
    lens = sc['_lens']
    starts = np.concatenate([[0], np.cumsum(lens)[:-1]])
    Lpx = float(lens.sum())
    Rc = ros[-1]
    sc_cap = Lpx - Rc
    esign = -1.0 if sc['_bend_sign'] > 0 else 1.0   # thin wall on the convex side
    has_lumen = tb.get('id_frac', 0.6) > 0 and not tb.get('opaque')

    def sec(s):
        return np.clip(np.searchsorted(starts, s, 'right') - 1, 0, len(lens) - 1)

    def radius(s):
        r = ros[sec(s)]
        cap = s > sc_cap
        return np.where(cap, np.sqrt(np.maximum(Rc * Rc - (s - sc_cap) ** 2, 0)), r)

    def lumen(s):
        li = np.where(s > sc_cap, np.sqrt(np.maximum(ri * ri - (s - sc_cap) ** 2, 0)), ri)
        return li, esign * e[sec(s)]

    D = 2 * ro0      # absorbances and emission are given per outer diameter of path
    opt = dict(n_b=tb.get('n', N_PDMS), n_l=tb.get('n_lumen', N_AIR),
               mu=tb.get('absorb', 0.12) / D, mu_l=tb.get('lumen_absorb', 0.0) / D,
               mu_dye=tb.get('dye', 0.0) / D, emis=tb.get('emis', 0.0) / D)
    if tb.get('opaque'):
        opt['mu'] = 4.0
    return Body(curve, sc['_s_lo'], Lpx, radius, lumen if has_lumen else None, name='tube',
                cap=(sc_cap, Rc, ri), **opt)


def holder_bodies(sc, off=(0.0, 0.0)):
    h = sc.get('holder')
    if not h:
        return []
    ro0 = radii(sc)[0]
    bx, by = sc['base']
    X0, Y0 = bx + off[0], -(by + off[1])
    th = math.radians(sc['heading']) + math.pi
    Lh = 4000.0
    cv = Curve((X0, Y0), th, [Lh], [0.0], s0=0.0, max_len=48.0)
    k = h['kind']
    if k == 'clamp':
        return [Body(cv, 0.0, Lh, lambda s: np.full_like(s, h['half_w'] * ro0), kind='slab',
                     occ=h.get('trans', 0.03), name='clamp')]
    Rg0, sl = h['Rg'] * ro0, h.get('slope', 0.0)
    Rb0, slb = h['Rb'] * ro0, h.get('slope_b', h.get('slope', 0.0) * h['Rb'] / h['Rg'])
    n_m = sc['optics'].get('n_medium', N_WATER)
    return [Body(cv, 0.0, Lh, lambda s: Rg0 + sl * s, lambda s: (Rb0 + slb * s, 0 * s),
                 n_b=N_GLASS, n_l=n_m, mu=h.get('absorb', 0.04) / (2 * Rg0),
                 emis=h.get('glow', 0.0) / (2 * Rg0),
                 face_scatter=h.get('face', 0.5), face_w=h.get('face_w', 0.7), name=k)]


def clutter_bodies(sc, off=(0.0, 0.0)):
    fld = sc.get('field', {})
    out = []
    for b in fld.get('bubbles', []):
        cx, cy, R = b
        out.append(Sphere(cx + off[0], -(cy + off[1]), R))
    for fb in fld.get('fibres', []):
        (cx, cy), th, lens, kaps, rad, mu = fb
        P0 = (cx + off[0], -(cy + off[1]))
        cv = Curve(P0, math.radians(th), lens, kaps, max_len=48.0)
        out.append(Body(cv, 0.0, cv.s1, lambda s, r=rad: np.full_like(s, r), n_b=1.53,
                        mu=mu, name='fibre'))
    return out


# ----------------------------------------------------------------------------- field / camera
def smooth_noise(rng, shape, sigma):
    z = rng.standard_normal(shape).astype(np.float32)
    z = cv2.GaussianBlur(z, (0, 0), sigma)
    return z / (z.std() + 1e-12)


def illumination(sc, shape):
    """Lamp field on the canvas (camera-fixed): vignetting, gradient, sensor dust."""
    Hc, Wc = shape
    fld = sc.get('field', {})
    rng = np.random.default_rng(seed_of(sc['name'], 'illum'))
    rr, cc = np.mgrid[0:Hc, 0:Wc].astype(np.float32)
    yc, xc = (Hc - 1) / 2.0, (Wc - 1) / 2.0
    vc = fld.get('vignette_centre', (0.0, 0.0))
    rad = np.hypot((cc - xc - vc[0] * Wc) / (Wc / 2), (rr - yc - vc[1] * Hc) / (Hc / 2)) / math.sqrt(2)
    v = fld.get('vignette', 0.15)
    I = (1 - v * rad ** 2 - 0.5 * v * rad ** 4).astype(np.float32)
    g = fld.get('gradient', (0.0, 0.0))
    I *= 1 + g[0] * (cc - xc) / Wc + g[1] * (rr - yc) / Hc
    for _ in range(fld.get('dust', 0)):
        x, y = rng.uniform(0, Wc), rng.uniform(0, Hc)
        R = rng.uniform(4, 16)
        depth = rng.uniform(0.04, 0.12)
        d = np.hypot(cc - x, rr - y)
        ring = np.exp(-0.5 * ((d - R) / (0.25 * R)) ** 2) + 0.5 * (d < R)
        I *= (1 - depth * np.clip(ring, 0, 1.2)).astype(np.float32)
    return np.maximum(I, 0.05)


def texture(sc, shape, extra):
    """Stage-fixed uneven background (absorbance of agar / dish), larger by `extra` px."""
    fld = sc.get('field', {})
    amp = fld.get('texture', 0.0)
    Hc, Wc = shape
    if amp <= 0:
        return None
    rng = np.random.default_rng(seed_of(sc['name'], 'texture'))
    sh = (Hc + 2 * extra, Wc + 2 * extra)
    z = 0.7 * smooth_noise(rng, sh, 2.5) + 0.6 * smooth_noise(rng, sh, 12) \
        + 0.5 * smooth_noise(rng, sh, 60)
    return np.exp(-amp * z).astype(np.float32)


def blur(img, sigma):
    if sigma <= 0.05:
        return img
    return cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)


def camera(sc, I, rng):
    """Relative intensity (1 = mean background at full exposure) -> integer frame."""
    cam = sc['camera']
    fw = cam.get('full_well', 8000.0)
    level = cam.get('level', 0.78)       # where 1.0 lands in the output range
    bits = cam.get('bits', 8)
    top = cam.get('top', 255 if bits == 8 else 65535)
    e = np.maximum(I, 0) * fw * level
    e = e + np.sqrt(e) * rng.standard_normal(e.shape).astype(np.float32) \
        + cam.get('read', 6.0) * rng.standard_normal(e.shape).astype(np.float32)
    v = e / fw                              # 0..1 of the camera's range
    if cam.get('gamma'):
        v = np.clip(v, 0, None) ** (1.0 / cam['gamma'])
    dn = cam.get('offset', 0) + v * top
    dn = np.clip(np.round(dn), 0, top)
    if cam.get('shift'):
        dn = dn * (2 ** cam['shift'])
    return dn.astype(np.uint8 if bits == 8 else np.uint16)


# ----------------------------------------------------------------------------- prepare
def prepare(sc):
    """Fill in derived geometry: sections, curvatures, placement."""
    sc['n'] = len(sc['bends'])
    sc['_lens'], sc['_kap'] = tube_sections(sc)
    bends = np.array(sc['bends'])
    sc['_bend_sign'] = 1.0 if bends[np.argmax(np.abs(bends))] >= 0 else -1.0
    if 'bend_sign' in sc['tube']:
        sc['_bend_sign'] = sc['tube']['bend_sign']
    ro0, ri, ros, e = radii(sc)
    W, H = sc['W'], sc['H']
    h = sc.get('holder')
    diag = math.hypot(W, H) + 2 * PAD
    if h is None or h['kind'] in ('capillary', 'clamp'):
        sc['_back'] = diag          # tube straight behind the base, out of the canvas
        sc['_s_lo'] = -diag
    else:
        sc['_back'] = 0.0
        sc['_s_lo'] = 0.0
    if sc.get('base') == 'auto':
        # centre the union of all frames' bodies in the frame (plus a shift)
        pts = []
        sc['base'] = (0.0, 0.0)
        for f in range(sc['n']):
            cv = tube_curve(sc, f)
            pts.append(cv.points(np.linspace(0, cv.s1, 200)))
        pts = np.concatenate(pts)
        lo, hi = pts.min(0), pts.max(0)
        cx, cy = (lo + hi) / 2
        sh = sc.get('base_shift', (0.0, 0.0))
        bx = (W - 1) / 2.0 - cx + sh[0]
        by = (H - 1) / 2.0 + cy + sh[1]          # row = -Y
        sc['base'] = (round(bx * 4) / 4, round(by * 4) / 4)
    return sc


# ----------------------------------------------------------------------------- planning
def plan(sc):
    """Margins, crossings and curvature checks per frame."""
    ro0, ri, ros, e = radii(sc)
    W, H = sc['W'], sc['H']
    offs = frame_offsets(sc)
    Lpx = float(sc['_lens'].sum())
    rep = dict(margin=1e9, self_cross=[], self_touch=[], holder_cross=[], min_sep=1e9,
               max_kr=0.0)
    h = sc.get('holder')
    for f in range(sc['n']):
        cv = tube_curve(sc, f, offs[f])
        s = np.arange(0, Lpx, 0.5)
        p = cv.points(s)
        col, row = p[:, 0], -p[:, 1]
        r = ros.max()
        m = np.minimum.reduce([col + 0.5 - r, W - 0.5 - col - r, row + 0.5 - r, H - 0.5 - row - r])
        if sc.get('border'):
            m = m[s > 3 * r]
        rep['margin'] = min(rep['margin'], float(m.min()))
        rep['max_kr'] = max(rep['max_kr'], float(np.abs(sc['_kap'][f]).max() * ros.max()))
        # self approach: points more than 3 diameters + a half turn apart along s
        q = p[::4]
        sq = s[::4]
        D = np.hypot(q[:, None, 0] - q[None, :, 0], q[:, None, 1] - q[None, :, 1])
        far = np.abs(sq[:, None] - sq[None, :]) > max(8 * r, math.pi / max(
            np.abs(sc['_kap'][f]).max(), 1e-9) * 0.9)
        if far.any():
            md = float(D[far].min())
            rep['min_sep'] = min(rep['min_sep'], md / (2 * r))
            if md < 2 * r:
                rep['self_cross'].append(f)
            elif md < 2.3 * r:
                rep['self_touch'].append(f)
        if h and h['kind'] != 'none':
            bx, by = sc['base']
            X0, Y0 = bx + offs[f][0], -(by + offs[f][1])
            th = math.radians(sc['heading'])
            dx, dy = p[:, 0] - X0, p[:, 1] - Y0
            uh = -(dx * math.cos(th) + dy * math.sin(th))
            vh = -dx * math.sin(th) + dy * math.cos(th)
            Rg = (h.get('Rg', h.get('half_w', 1))) * ro0 + h.get('slope', 0) * np.maximum(uh, 0)
            if ((uh > 0) & (np.abs(vh) < Rg + r) & (s > 4 * r)).any():
                rep['holder_cross'].append(f)
    return rep


# ----------------------------------------------------------------------------- rendering
def render_scene(sc, write=True, frames=None):
    t0 = time.time()
    sc = prepare(dict(sc))
    name = sc['name']
    W, H = sc['W'], sc['H']
    Hc, Wc = H + 2 * PAD, W + 2 * PAD
    opt = sc['optics']
    n_m = opt.get('n_medium', N_WATER)
    oo = dict(n_m=n_m, a_o=math.asin(opt.get('NA', 0.2) / n_m),
              a_c=math.asin(opt.get('NA_c', 0.6 * opt.get('NA', 0.2)) / n_m))
    S = sc.get('S', 4)
    lat = lattice(S)
    look = sc.get('look', 'bf')
    colour = sc.get('colour')
    kdye = colour['dye'] if colour else [1.0]
    offs = frame_offsets(sc)
    moving = bool(np.abs(offs).max() > 0)
    fld = sc.get('field', {})
    illum = illumination(sc, (Hc, Wc))
    extra = int(np.ceil(np.abs(offs).max())) + 4
    tex = texture(sc, (Hc, Wc), extra)
    flick = np.ones(sc['n'])
    if 'flicker' in fld:
        rng_f = np.random.default_rng(seed_of(name, 'flicker'))
        a, per = fld['flicker']
        ff = np.arange(sc['n'])
        flick = 1 + a * np.sin(2 * np.pi * ff / per + 1.0) + 0.4 * a * rng_f.standard_normal(sc['n'])
    static_cache = {}
    outdir = os.path.join(SCENES_DIR, name)
    frames_out = []
    truth_rows, cl_rows = [], []
    um = sc['um']
    Lpx = float(sc['_lens'].sum())
    idx = range(sc['n']) if frames is None else frames
    for f in idx:
        off = tuple(offs[f])
        key = off if moving else (0.0, 0.0)
        if key not in static_cache:
            parts = []
            for b in holder_bodies(sc, key) + clutter_bodies(sc, key):
                parts += body_layers(b, oo, lat, (Hc, Wc))
            st = Layered(parts, S * S)
            Tst, Est, Pst = st.pixel_values(kdye, look != 'phase')
            static_cache.clear()
            static_cache[key] = (st, Tst, Est, Pst)
        st, Tst, Est, Pst = static_cache[key]
        cv = tube_curve(sc, f, off)
        tube = make_tube_body(sc, cv)
        lay = Layered(body_layers(tube, oo, lat, (Hc, Wc)), S * S)
        lay.merge_static(st)
        T, E, P = lay.pixel_values(kdye, look != 'phase')
        # canvas images
        nch = len(kdye)
        Timg = [np.ones(Hc * Wc, np.float32) for _ in range(nch)]
        Eimg = np.zeros(Hc * Wc, np.float32)
        Pimg = np.zeros(Hc * Wc, np.float32)
        if len(st.ids):
            for c in range(nch):
                Timg[c][st.ids] = Tst[c]
            Eimg[st.ids] = Est
            Pimg[st.ids] = Pst
        for c in range(nch):
            Timg[c][lay.ids] = T[c]
        Eimg[lay.ids] = E
        Pimg[lay.ids] = P
        Timg = [t.reshape(Hc, Wc) for t in Timg]
        Eimg, Pimg = Eimg.reshape(Hc, Wc), Pimg.reshape(Hc, Wc)
        # stage-fixed texture
        if tex is not None:
            dx, dy = off
            M = np.float32([[1, 0, extra - dx], [0, 1, extra - dy]])
            tx = cv2.warpAffine(tex, M, (Wc, Hc), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                borderMode=cv2.BORDER_REFLECT)
        else:
            tx = 1.0
        img = apply_look(sc, look, Timg, Eimg, Pimg, illum * flick[f], tx, f)
        img = img[:, PAD:PAD + H, PAD:PAD + W]
        rng = np.random.default_rng(seed_of(name, 'frame', f))
        if colour and colour.get('lateral'):
            img = lateral_ca(img, colour['lateral'])
        fr = np.stack([camera(sc, img[c], rng) for c in range(img.shape[0])], -1)
        frames_out.append(fr if fr.shape[-1] > 1 else fr[..., 0])
        # truth
        n_iv = int(math.ceil(Lpx / 0.3))
        s = np.concatenate([[0.0, 0.002], np.linspace(0, Lpx, n_iv + 1)[1:-1], [Lpx - 0.002, Lpx]])
        p = cv.points(s)
        bend = float(sc['bends'][f])
        truth_rows.append((f, f / sc['fps'], bend, p[-1, 0] * um, p[-1, 1] * um, p[0, 0] * um,
                           p[0, 1] * um, Lpx * um))
        cl_rows.append((f, s * um, p[:, 0] * um, p[:, 1] * um))
    if not write:
        return sc, frames_out, truth_rows, cl_rows
    if os.path.exists(outdir):
        shutil.rmtree(outdir)
    os.makedirs(outdir)
    inp, info = write_frames(sc, outdir, frames_out)
    with open(os.path.join(outdir, 'truth_tracks.csv'), 'w') as fh:
        fh.write('frame,time_s,bend_angle_deg,tip_x_um,tip_y_um,base_x_um,base_y_um,length_um,status\n')
        for r in truth_rows:
            fh.write('%d,%.6f,%.7f,%.7f,%.7f,%.7f,%.7f,%.7f,ok\n' % r)
    with open(os.path.join(outdir, 'truth_centrelines.csv'), 'w') as fh:
        fh.write('frame,s_um,x_um,y_um\n')
        for f, s, x, y in cl_rows:
            fh.write(''.join('%d,%.7f,%.7f,%.7f\n' % (f, a, b, c) for a, b, c in zip(s, x, y)))
    rep = plan(sc)
    meta = scene_json(sc, inp, info, rep)
    with open(os.path.join(outdir, 'scene.json'), 'w') as fh:
        json.dump(meta, fh, indent=1)
    return time.time() - t0


def lateral_ca(img, k):
    """Lateral chromatic aberration: red magnified by (1+k), blue by (1-k) about the centre."""
    C, H, W = img.shape
    out = img.copy()
    for c, m in ((0, 1 + k), (2, 1 - k)):
        M = np.float32([[1 / m, 0, (W - 1) / 2 * (1 - 1 / m)], [0, 1 / m, (H - 1) / 2 * (1 - 1 / m)]])
        out[c] = cv2.warpAffine(img[c], M, (W, H), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                borderMode=cv2.BORDER_REFLECT)
    return out


def apply_look(sc, look, Timg, Eimg, Pimg, illum, tx, f):
    """Canvas images of the specimen -> relative intensity per channel (C, Hc, Wc)."""
    opt = sc['optics']
    sig = opt.get('psf', 1.0)
    colour = sc.get('colour')
    out = []
    if look == 'bf':
        lamp = colour['lamp'] if colour else [1.0]
        sigs = colour.get('psf', [sig] * 3) if colour else [sig]
        for c, t in enumerate(Timg):
            out.append(blur(illum * lamp[c] * tx * t, sigs[c]))
    elif look == 'phase':
        ph = opt['phase']
        hp = Pimg - blur(Pimg, ph['halo_sigma'])
        mod = 1 - ph['a'] * np.tanh(hp / ph['p0'])
        out.append(blur(illum * tx * Timg[0] * mod, sig))
    elif look == 'fluor':
        fl = opt['fluor']
        em = Eimg + fl.get('haze', 0.1) * blur(Eimg, fl.get('haze_sigma', 25))
        bleach = math.exp(-fl.get('bleach', 0.0) * f)
        out.append(blur(fl.get('bg', 0.05) * tx + illum * fl['gain'] * bleach * em, sig))
    elif look == 'tie':
        tz = opt['tie']
        Hc, Wc = Pimg.shape
        rr, cc = np.mgrid[0:Hc, 0:Wc].astype(np.float32)
        dz = (tz['z0'] + tz['zx'] * (cc - Wc / 2) / Wc + tz['zy'] * (rr - Hc / 2) / Hc
              + tz.get('zt', 0.0) * f)
        base = illum * tx * Timg[0]
        levels = np.linspace(np.abs(dz).min(), np.abs(dz).max(), 6)
        sigs = np.hypot(sig, tz['blur_per_z'] * levels)
        stack = np.stack([blur(base, s_) for s_ in sigs])
        w = np.interp(np.abs(dz), levels, np.arange(6))
        i0 = np.clip(np.floor(w).astype(int), 0, 4)
        a = (w - i0).astype(np.float32)
        img = np.take_along_axis(stack, i0[None], 0)[0] * (1 - a) \
            + np.take_along_axis(stack, (i0 + 1)[None], 0)[0] * a
        lap = cv2.Laplacian(blur(Pimg, tz.get('lap_sigma', 1.5)), cv2.CV_32F)
        # transport-of-intensity halo: dI/I ~ -dz * laplacian(optical path), saturated smoothly
        out.append(np.maximum(img * (1 - 0.6 * np.tanh(tz['k'] * dz * lap / 0.6)), 0.0))
    else:
        raise ValueError(look)
    return np.stack(out).astype(np.float32)


# ----------------------------------------------------------------------------- writing
def write_frames(sc, outdir, frames):
    fm = sc['format']
    kind = fm['kind']
    fps = sc['fps']
    H, W = frames[0].shape[:2]
    colour = frames[0].ndim == 3
    info = dict(kind=kind)
    if kind in ('avi_mjpg', 'avi_ffv1', 'mp4'):
        fcc = {'avi_mjpg': 'MJPG', 'avi_ffv1': 'FFV1', 'mp4': 'mp4v'}[kind]
        fn = 'video.mp4' if kind == 'mp4' else 'video.avi'
        vw = cv2.VideoWriter(os.path.join(outdir, fn), cv2.VideoWriter_fourcc(*fcc), fps, (W, H),
                             isColor=colour)
        if kind == 'avi_mjpg' and 'quality' in fm:
            vw.set(cv2.VIDEOWRITER_PROP_QUALITY, fm['quality'])
        assert vw.isOpened()
        for fr in frames:
            vw.write(cv2.cvtColor(fr, cv2.COLOR_RGB2BGR) if colour else fr)
        vw.release()
        info['fourcc'] = fcc
        return fn, info
    if kind == 'gif':
        fn = 'video.gif'
        ims = [Image.fromarray(fr) for fr in frames]
        ims[0].save(os.path.join(outdir, fn), save_all=True, append_images=ims[1:],
                    duration=int(round(1000 / fps)), loop=0, optimize=False, disposal=1)
        return fn, info
    if kind == 'tif_stack':      # one series, one page per frame
        fn = 'stack.tif'
        tifffile.imwrite(os.path.join(outdir, fn), np.stack(frames),
                         photometric='rgb' if colour else 'minisblack',
                         compression=fm.get('compression'))
        info['compression'] = fm.get('compression') or 'none'
        return fn, info
    # folders
    d = os.path.join(outdir, 'frames')
    os.makedirs(d)
    pat = fm['pattern']
    for i, fr in enumerate(frames):
        p = os.path.join(d, pat % (i + fm.get('first', 0)))
        if p.endswith('.tif'):
            tifffile.imwrite(p, fr, photometric='rgb' if colour else 'minisblack')
        elif p.lower().endswith(('.jpg', '.jpeg')):
            cv2.imwrite(p, cv2.cvtColor(fr, cv2.COLOR_RGB2BGR) if colour else fr,
                        [cv2.IMWRITE_JPEG_QUALITY, fm.get('quality', 90)])
        else:
            cv2.imwrite(p, cv2.cvtColor(fr, cv2.COLOR_RGB2BGR) if colour else fr,
                        [cv2.IMWRITE_PNG_COMPRESSION, 3])
    info['pattern'] = pat
    return 'frames', info


def scene_json(sc, inp, info, rep):
    ro0, ri, ros, e = radii(sc)
    settings = {k: v for k, v in sc.items() if not k.startswith('_') and k not in (
        'name', 'description', 'tests', 'bends')}
    settings['bends_deg'] = [round(float(b), 6) for b in sc['bends']]
    Lpx = float(sc['_lens'].sum())
    derived = dict(outer_radius_px=[round(float(r), 4) for r in ros], lumen_radius_px=round(ri, 4),
                   lumen_offset_px=[round(float(x), 4) for x in e * (-sc['_bend_sign'])],
                   length_px=round(Lpx, 4), section_lengths_px=[round(float(x), 4) for x in sc['_lens']],
                   base_px=list(sc['base']), min_margin_px=round(rep['margin'], 2),
                   max_curvature_x_radius=round(rep['max_kr'], 3),
                   min_separation_diameters=round(rep['min_sep'], 3),
                   frames_crossing_itself=rep['self_cross'], frames_touching_itself=rep['self_touch'],
                   frames_over_holder=rep['holder_cross'], seed=seed_of(sc['name'], 'frame', 0),
                   file=info)
    return dict(name=sc['name'], description=sc['description'], tests=sc['tests'],
                um_per_px=sc['um'], input=inp, n_frames=sc['n'], fps=sc['fps'],
                frame_size=[sc['W'], sc['H']], settings=settings, derived=derived,
                conventions=CONVENTIONS)


CONVENTIONS = (
    "pixel (col,row) centre at (col,row); x_um = col*um_per_px, y_um = -row*um_per_px (y up); "
    "bend = unwrapped CCW rotation of the tip tangent relative to the base tangent (clockwise < 0); "
    "base = where the tube leaves its holder's end face (no holder: where the centreline crosses "
    "the frame's outer pixel edge); tip = apex of the closed hemispherical cap (radius = outer "
    "radius of the last section; half-width sqrt(Rc^2-(s-(L-Rc))^2) over the last Rc of arc, "
    "following the centreline); length_um = arc length base->tip; centreline = chain of exact "
    "circular arcs (one per section), points every <= 0.3 px plus one 0.002 px from each end; "
    "frame 0-based, time_s = frame/fps.")

# ----------------------------------------------------------------------------- scenes
def ease(n, b0, b1):
    """n frames from b0 to b1, smoothstep in time (slow start and end)."""
    t = np.linspace(0, 1, n)
    return list(b0 + (b1 - b0) * t * t * (3 - 2 * t))


def ramp(n, b0, b1):
    return list(np.linspace(b0, b1, n))


def hold(lst, k):
    return list(lst) + [lst[-1]] * k


def spiral(L_um, od_um, turn_deg, n_sec, gap, outward=False):
    """Sections (frac, ratio) whose arcs follow a spiral R(phi) = R0 -/+ a*phi at the full turn
    (a = gap*OD/2pi): each turn lies `gap` diameters inside (outside) the previous one."""
    Phi = math.radians(abs(turn_deg))
    a = gap * od_um / (2 * math.pi) * (-1 if outward else 1)
    R0 = (L_um + a * Phi ** 2 / 2) / Phi
    ph = np.linspace(0, Phi, n_sec + 1)
    lens = R0 * np.diff(ph) - a * np.diff(ph ** 2) / 2
    kap = np.diff(ph) / lens
    return [dict(frac=round(float(f), 6), ratio=round(float(r), 6))
            for f, r in zip(lens / lens.sum(), kap / kap.mean())]


def lead_spiral(L_um, od_um, turn_deg, lead_frac, lead_deg, n_sec, gap, outward=False):
    """A stiff lead section (lead_frac of the length, turning lead_deg at the full bend) followed
    by the spiral() sections over the rest, turning turn_deg - lead_deg."""
    L2 = L_um * (1 - lead_frac)
    sp = spiral(L2, od_um, abs(turn_deg) - abs(lead_deg), n_sec, gap, outward)
    Phi2 = math.radians(abs(turn_deg) - abs(lead_deg))
    lens = np.array([s['frac'] for s in sp]) * L2
    kap_mean = Phi2 / float((lens * np.array([q['ratio'] for q in sp])).sum())
    k1 = math.radians(abs(lead_deg)) / (L_um * lead_frac)
    out = [dict(frac=lead_frac, ratio=round(k1 / kap_mean, 6))]
    out += [dict(frac=round(s['frac'] * (1 - lead_frac), 6), ratio=s['ratio']) for s in sp]
    return out


def S(name, description, tests, **kw):
    """A scene with defaults (water, brightfield, 8-bit camera)."""
    sc = dict(name=name, description=description, tests=tests, fps=10.0, look='bf', S=5,
              base='auto', optics=dict(NA=0.08, psf=1.0, n_medium=N_WATER),
              camera=dict(full_well=8000.0, read=6.0, bits=8, level=0.78), field=dict(vignette=0.15))
    for k, v in kw.items():
        if isinstance(v, dict) and isinstance(sc.get(k), dict):
            sc[k] = dict(sc[k], **v)
        else:
            sc[k] = v
    return sc


def _secs(base, **per):
    """Merge per-section lists (od_scale=[...], ecc=[...]) into section dicts."""
    out = [dict(s) for s in base]
    for k, vals in per.items():
        for s, v in zip(out, vals):
            s[k] = v
    return out


SCENES = [
    # ------------------------------------------------------------------ over-curls
    S('oc_coil_inside_touch_ffv1',
      'brightfield (water, air lumen visible), thin glass pipette (0.55x the tube width) from the left, '
      '4 sections (walls and outer width step slightly) laid out as an inward spiral: curls CCW to '
      '600 deg (1.67 turns) where the second turn lies inside the first, touching it (centre '
      'distance ~1.0 OD) over ~240 deg of arc; 18 px wide; 960x720; FFV1 AVI',
      'over-curl whose coils lie along each other and touch over a long stretch (edges between the '
      'coils shared); multi-section; unwrapping past 360',
      W=960, H=720, um=350 / 18, heading=0.0,
      tube=dict(od_um=350, L_um=9000, id_frac=0.58, ecc=0.25,
                sections=_secs(spiral(9000, 350, 600, 4, 1.09), od_scale=[1.03, 1.01, 0.99, 0.97])),
      holder=dict(kind='pipette', Rg=0.55, Rb=0.25, slope=0.03), optics=dict(NA=0.09),
      bends=hold(ease(26, 0, 600), 4), format=dict(kind='avi_ffv1'), cost=2),
    S('oc_coil_outside_phase_mp4',
      'phase contrast (water-filled tube: dark, with a bright halo), thin glass pipette narrower than the tube (0.5x) from '
      'the top-right corner (tube heading 230 deg), 4 sections laid out as an outward spiral: curls '
      'clockwise to -500 deg; from ~-310 deg the last turn passes close beside the pipette, then lies '
      'along the outside of the first turn, touching it; 14 px wide; 960x720; MP4 (mp4v)',
      'clockwise over-curl in phase contrast; outer coil lying along the first; tip passing the holder',
      W=960, H=720, um=300 / 14, heading=230.0,
      tube=dict(od_um=300, L_um=10000, id_frac=0.6, ecc=0.2, n_lumen=N_WATER,
                sections=spiral(10000, 300, 500, 4, 1.04, outward=True)),
      holder=dict(kind='pipette', Rg=0.5, Rb=0.25, slope=0.04), look='phase',
      optics=dict(NA=0.1, psf=1.1, phase=dict(a=0.6, p0=0.8, halo_sigma=8.0)),
      bends=hold(ease(30, 0, -500), 4), format=dict(kind='mp4'), cost=2),
    S('oc_tip_over_capillary_fluor_tif16',
      'fluorescence (dye in the PDMS wall; lumen dark), faintly glowing glass capillary 2.4x the tube '
      'width from the bottom (tube heading 90 deg), 3 sections as an outward spiral: curls CCW to 430 '
      'deg: the last turn crosses over the capillary\'s end, then lies along the outside of the first '
      'turn, touching it; 20 px wide; '
      '900x700; 12-bit camera in a 16-bit multi-page TIFF; slight bleaching',
      'over-curl in a bright look with the tip region over a glowing holder; 16-bit TIFF stack',
      W=900, H=700, um=20.0, heading=90.0,
      tube=dict(od_um=400, L_um=9500, id_frac=0.6, ecc=0.2, emis=1.0,
                sections=spiral(9500, 400, 430, 3, 1.0, outward=True)),
      holder=dict(kind='capillary', Rg=2.4, Rb=1.15, glow=0.12), look='fluor',
      optics=dict(NA=0.1, psf=1.2, fluor=dict(gain=0.9, bg=0.06, haze=0.12, haze_sigma=30,
                                                bleach=0.004)),
      camera=dict(bits=16, top=4095, offset=96, full_well=5000.0, read=3.0, level=0.85),
      field=dict(vignette=0.2), bends=hold(ease(30, 0, 430), 2),
      format=dict(kind='tif_stack', compression='zlib'), cost=2),
    S('oc_shallow_tip_across_base_png',
      'tube in air (brightfield, low NA: a dark tube with a bright central line, dark glass), thin '
      'pipette (0.7x) from the left at 20 deg, stiff first section (25 %, ratio 0.15) then a '
      'uniform curl: clockwise to -400 deg; from ~-370 deg the tip region lies across the tube\'s '
      'own straight base stretch at 2-20 deg; 16 px wide; 800x600; PNG folder frame_1.png ... '
      'frame_38.png (natural order)',
      'tip lying across its own base stretch at a shallow angle; tube-in-air look; natural sort',
      W=800, H=600, um=20.0, heading=20.0,
      tube=dict(od_um=320, L_um=9500, id_frac=0.55, ecc=0.2,
                sections=[dict(frac=0.25, ratio=0.15), dict(frac=0.375), dict(frac=0.375)]),
      holder=dict(kind='pipette', Rg=0.7, Rb=0.35, slope=0.03), optics=dict(NA=0.08, n_medium=N_AIR),
      bends=hold(ease(34, 0, -400), 4), format=dict(kind='png_dir', pattern='frame_%d.png', first=1),
      cost=1.5),
    S('oc_opaque_black_coil_mjpg',
      'opaque (carbon-black) tube: a silhouette with no interior, held in a dark metal clamp from the '
      'right (tube heading 180 deg); a stiff lead section (30 %) then 3 sections as an inward spiral: '
      'curls CCW to 540 deg (1.5 turns) where the last half turn lies inside the first, touching '
      'it (centre distance 1.00 OD); 22 px wide; '
      '960x720; MJPG AVI',
      'over-curl of an opaque tube: touching coils merge into one dark band; clamp holder',
      W=960, H=720, um=450 / 22, heading=180.0,
      tube=dict(od_um=450, L_um=11000, opaque=True,
                sections=lead_spiral(11000, 450, 540, 0.3, 15, 3, 1.02)),
      holder=dict(kind='clamp', half_w=3.5, trans=0.04), optics=dict(NA=0.08),
      bends=hold(ease(28, 0, 540), 3), format=dict(kind='avi_mjpg', quality=85), cost=2),
    S('oc_five_frames_0_540_mjpg',
      'only 5 frames: 0, 135, 270, 405, 540 deg (inward spiral, 3 sections); brightfield, thin '
      'pipette from the left at -10 deg; 12 px wide; 640x480; MJPG AVI at 1 fps',
      'very few frames with 135 deg between them, ending past a full turn',
      W=640, H=480, um=280 / 12, heading=-10.0, fps=1.0,
      tube=dict(od_um=280, L_um=8500, sections=spiral(8500, 280, 540, 3, 1.3)),
      holder=dict(kind='pipette', Rg=0.6, Rb=0.3, slope=0.03),
      bends=[0.0, 135.0, 270.0, 405.0, 540.0], format=dict(kind='avi_mjpg', quality=90)),
    S('oc_deflate_from_620_png16',
      'starts curled to -620 deg (1.72 turns, an inward spiral, 3 sections, strongly eccentric '
      'lumen) and deflates to its rest shape (-24 deg, pre-curved) then holds; brightfield; thin '
      'pipette from the lower left at 35 deg; 20 px wide; 1024x768; 16-bit PNG folder (12-bit '
      'camera, left-aligned: counts x16)',
      'first frame already over-curled (no straight frame to start from); deflation; rest shape bent',
      W=1024, H=768, um=19.0, heading=35.0,
      tube=dict(od_um=380, L_um=10500, id_frac=0.55,
                sections=_secs(spiral(10500, 380, 620, 3, 1.2), ecc=[0.4, 0.45, 0.5],
                               rest_deg=[-8.0, -8.0, -8.0])),
      holder=dict(kind='pipette', Rg=0.55, Rb=0.25, slope=0.035), optics=dict(NA=0.09),
      camera=dict(bits=16, top=4095, shift=4, full_well=20000.0, read=8.0),
      bends=hold(ease(33, -620, -24), 3), format=dict(kind='png_dir', pattern='img_%04d.png'),
      cost=2),
    S('oc_rgb_dyed_crossing_mp4',
      'colour brightfield under a halogen lamp, red-dyed tube (absorbs green and blue), lateral '
      'chromatic aberration, glass capillary 1.4x from the top-left corner (tube heading -45 deg); '
      '3 sections (0.6 : 1 : 1.5): curls CCW to 620 deg (1.72 turns); from ~530 deg the tip region '
      'runs onto the first turn at ~20-28 deg and lies across it (centre lines 0.33 OD apart at the '
      'tip at the end); 16 px wide; 800x600; MP4 (mp4v), colour',
      'over-curl crossing itself in colour frames; corner holder',
      W=800, H=600, um=330 / 16, heading=-45.0,
      tube=dict(od_um=330, L_um=9000, dye=0.8, sections=[
          dict(frac=0.34, ratio=0.6), dict(frac=0.33, ratio=1.0), dict(frac=0.33, ratio=1.5)]),
      holder=dict(kind='capillary', Rg=1.4, Rb=1.08), optics=dict(NA=0.08, NA_c=0.3),
      colour=dict(lamp=[1.0, 0.86, 0.62], dye=[0.12, 1.0, 0.85], lateral=4e-4, psf=[1.2, 1.0, 1.35]),
      bends=hold(ease(32, 0, 620), 2), format=dict(kind='mp4'), cost=1.5),
    S('oc_border_entry_cw_ffv1',
      'no holder: the tube enters across the bottom border (heading 72 deg) and curls clockwise to '
      '-430 deg: a stiff lead section (30 %) then an inward spiral (3 sections, next turn 1.15 OD '
      'inside); brightfield; 13 px '
      'wide; 768x768; FFV1 AVI',
      'border base with an over-curl; unwrapping; square frame',
      W=768, H=768, um=300 / 13, heading=72.0, border=True, base=(310.0, 767.5),
      tube=dict(od_um=300, L_um=10000, sections=lead_spiral(10000, 300, 430, 0.3, 20, 3, 1.15)),
      holder=None, bends=hold(ease(30, 0, -430), 2), format=dict(kind='avi_ffv1')),
    S('oc_tip_along_capillary_tifdir',
      'brightfield, thick glass capillary 3x the tube width from the right (tube heading 180 deg); '
      'straight first and last sections (30 % and 57 %, which do not bend) and a short bending one '
      '(13 %): the tube makes a U-turn and its last stretch comes back parallel to the base stretch '
      'and lies along the capillary\'s side, 0.1-0.5 tube radius from the glass, over ~115 px at the '
      'end; CW to -181 deg; 15 px wide; 800x600; 8-bit TIFF folder Pos0_t1.tif ...',
      'tip lying along the holder (two parallel bodies, no crossing); TIFF folder, natural order',
      W=800, H=600, um=20.0, heading=180.0, base_shift=(0.0, 0.0),
      tube=dict(od_um=300, L_um=8500, sections=[
          dict(frac=0.3, ratio=0.0), dict(frac=0.13, ratio=1.0), dict(frac=0.57, ratio=0.0)]),
      holder=dict(kind='capillary', Rg=3.0, Rb=1.15), optics=dict(NA=0.09, NA_c=0.2),
      bends=hold(ease(28, 0, -181), 3), format=dict(kind='tif_dir', pattern='Pos0_t%d.tif', first=1)),
    # ------------------------------------------------------------------ multi-section
    S('sec4_eccentric_png16',
      'brightfield, 4 sections whose walls differ (outer width 1.00 : 0.95 : 1.04 : 0.93, lumen '
      'offset 0.35-0.6 of the wall, curvature ratios 0.6 : 1.5 : 0.8 : 1.9): a chain of arcs with '
      'steps in curvature and width at the joints; thin pipette from the lower left at 17 deg; CCW '
      'to 260 deg; 28 px wide; 1280x960; 16-bit PNG folder with 12-bit levels (0-4095)',
      'multi-section tube: curvature and width steps; eccentric lumen; 16-bit PNG',
      W=1280, H=960, um=15.0, heading=17.0,
      tube=dict(od_um=420, L_um=10000, id_frac=0.55, sections=_secs(
          [dict(frac=0.3, ratio=0.6), dict(frac=0.25, ratio=1.5), dict(frac=0.25, ratio=0.8),
           dict(frac=0.2, ratio=1.9)], od_scale=[1.0, 0.95, 1.04, 0.93],
          ecc=[0.35, 0.55, 0.3, 0.6])),
      holder=dict(kind='pipette', Rg=0.6, Rb=0.3, slope=0.03), optics=dict(NA=0.12, NA_c=0.12,
                                                                          psf=1.1),
      camera=dict(bits=16, top=4095, full_well=15000.0, read=5.0),
      bends=hold(ease(28, 0, 260), 2), format=dict(kind='png_dir', pattern='f%03d.png'), cost=2),
    S('sec3_capillary_inside_jpgdir',
      'brightfield, glass capillary 2.6x the tube width (bore 1.4x) from the top-left corner (tube '
      'heading -40 deg), the tube seen inside it for ~250 px; 3 sections (ratios 1.2 : 0.5 : 1.6, '
      'outer width 1.00 : 1.05 : 0.96); clockwise to -230 deg; vignetting; 18 px wide; 1024x768; '
      'JPEG folder img_1.jpg ... img_30.jpg',
      'tube inside a wide capillary (base at its end face, not at a width step of the tube); '
      'sections; JPEG; natural sort',
      W=1024, H=768, um=20.0, heading=-40.0, base_shift=(40.0, 0.0),
      tube=dict(od_um=360, L_um=9500, sections=_secs(
          [dict(frac=0.4, ratio=1.2), dict(frac=0.3, ratio=0.5), dict(frac=0.3, ratio=1.6)],
          od_scale=[1.0, 1.05, 0.96])),
      holder=dict(kind='capillary', Rg=2.6, Rb=1.4), field=dict(vignette=0.35),
      optics=dict(NA=0.08, NA_c=0.25),
      bends=ease(30, 0, -230), format=dict(kind='jpg_dir', pattern='img_%d.jpg', first=1, quality=88)),
    S('sec2_widthstep_fluor_gif',
      'fluorescence, 2 sections with a 14 % step in outer width at the joint (ratios 0.7 : 1.8), '
      'opaque clamp from the top (tube heading -90 deg, hanging down); CCW to 220 deg; 12 px wide; '
      '640x480; animated GIF (grey palette)',
      'width step and curvature step at a joint in a bright look; GIF input; dark clamp',
      W=640, H=480, um=25.0, heading=-90.0,
      tube=dict(od_um=300, L_um=8000, emis=1.0, sections=_secs(
          [dict(frac=0.55, ratio=0.7), dict(frac=0.45, ratio=1.8)], od_scale=[1.0, 0.86])),
      holder=dict(kind='clamp', half_w=4.0, trans=0.0), look='fluor',
      optics=dict(NA=0.1, psf=1.0, fluor=dict(gain=0.6, bg=0.05, haze=0.1, haze_sigma=20)),
      camera=dict(level=0.9, full_well=3000.0, read=4.0),
      bends=ease(28, 0, 220), format=dict(kind='gif')),
    # ------------------------------------------------------------------ holders, frames
    S('pipette_thin_corner_tifdir',
      'brightfield, thin tapered pipette (0.5x the tube width at its tip) from the bottom-left corner '
      'at 52 deg, one section with an eccentric lumen; clockwise to -170 deg; 13 px wide; 800x600; '
      '8-bit TIFF folder t1.tif ... t26.tif',
      'narrow holder from a corner at an odd angle (the width steps up at the base)',
      W=800, H=600, um=20.0, heading=52.0,
      tube=dict(od_um=260, L_um=8000, ecc=0.3, sections=[dict(frac=1.0)]),
      holder=dict(kind='pipette', Rg=0.5, Rb=0.22, slope=0.05),
      bends=ease(26, 0, -170), format=dict(kind='tif_dir', pattern='t%d.tif', first=1)),
    S('portrait_clamp_odd_mp4',
      'portrait 720x1280 (camera turned): opaque clamp from the top at heading -104 deg (the tube hangs '
      'down, slightly left), 2 sections (0.8 : 1.2); clockwise to -200 deg; 20 px wide; MP4 (mp4v)',
      'portrait frame; clamp at an odd angle; base at the top',
      W=720, H=1280, um=20.0, heading=-104.0,
      tube=dict(od_um=400, L_um=11000, sections=[dict(frac=0.5, ratio=0.8), dict(frac=0.5, ratio=1.2)]),
      holder=dict(kind='clamp', half_w=5.0, trans=0.05), optics=dict(NA=0.09),
      bends=ease(28, 0, -200), format=dict(kind='mp4'), cost=1.5),
    S('big_2560x1920_80px_jpgdir',
      'high magnification: 2560x1920, an 80 px wide tube (0.4 mm at 5 um/px), 9 mm = 1800 px long, '
      'lumen and its eccentricity clearly visible, glass capillary 1.4x from the left; 2 sections '
      '(0.8 : 1.2); CCW 0 -> 190 deg in 12 frames; JPEG folder frame_1.jpg ... frame_12.jpg',
      'very large frame and a very wide tube (binning), JPEG',
      W=2560, H=1920, um=5.0, heading=0.0, S=4,
      tube=dict(od_um=400, L_um=9000, ecc=0.25, sections=[dict(frac=0.5, ratio=0.8),
                                                         dict(frac=0.5, ratio=1.2)]),
      holder=dict(kind='capillary', Rg=1.4, Rb=1.06), optics=dict(NA=0.25, NA_c=0.25, psf=1.6),
      bends=ease(12, 0, 190), format=dict(kind='jpg_dir', pattern='frame_%d.jpg', first=1, quality=92),
      cost=4),
    S('small_320_150f_pngdir',
      'low magnification: 320x240, a 5.5 px wide, 165 px long tube; thin pipette (3.3 px) from the '
      'left; 150 frames: slow inflation to 230 deg over 100 frames (2.3 deg/frame), hold, deflation '
      'to 60 deg; PNG folder frame_1.png ... frame_150.png (natural order matters: frame_10 after '
      'frame_9)',
      'many frames, tiny tube, small frame, natural sort of 1-3 digit names',
      W=320, H=240, um=300 / 5.5, heading=0.0, S=7, fps=15.0,
      tube=dict(od_um=300, L_um=9000, sections=[dict(frac=1.0)]),
      holder=dict(kind='pipette', Rg=0.6, Rb=0.3, slope=0.02), optics=dict(NA=0.04, psf=0.8),
      bends=ease(100, 0, 230) + [230.0] * 10 + ease(41, 230, 60)[1:],
      format=dict(kind='png_dir', pattern='frame_%d.png', first=1), cost=2),
    S('rest_bent_deflate_tifstack8',
      'pre-curved tube (70 deg at rest, one section), thin pipette from the right (heading 180 deg); '
      'starts pressurised at 250 deg and deflates to its rest shape, then holds; brightfield; '
      '17 px wide; 800x600; 8-bit multi-page TIFF',
      'a video that starts bent and ends bent (never straight); deflation',
      W=800, H=600, um=20.0, heading=180.0,
      tube=dict(od_um=340, L_um=9500, sections=[dict(frac=1.0, rest_deg=70.0)], bend_sign=1.0),
      holder=dict(kind='pipette', Rg=0.65, Rb=0.3, slope=0.03),
      bends=hold(ease(24, 250, 70), 6), format=dict(kind='tif_stack')),
    S('fast_steps_wide_capillary_ffv1',
      'pressure steps: 75 deg jumps in single frames, up to 225 deg and back to 0 and up again; '
      'glass capillary 3x the tube width from the left at 10 deg; 30 px wide; 1280x960; FFV1 AVI',
      'large single-frame jumps up and down; very wide holder',
      W=1280, H=960, um=15.0, heading=10.0,
      tube=dict(od_um=450, L_um=10000, sections=[dict(frac=0.5, ratio=0.9), dict(frac=0.5, ratio=1.1)]),
      holder=dict(kind='capillary', Rg=3.0, Rb=1.15), optics=dict(NA=0.12, NA_c=0.3, psf=1.1),
      bends=[0, 0, 0, 75, 75, 75, 150, 150, 150, 225, 225, 225, 150, 150, 75, 75, 0, 0, 75, 150,
             225, 225], format=dict(kind='avi_ffv1'), cost=2),
    # ------------------------------------------------------------------ illumination and optics
    S('vignette_gradient_texture_mjpg',
      'strong vignetting (corners at ~35 %), an illumination gradient and an uneven, grainy '
      'background (agar); glass capillary 1.4x from the right (tube heading 180 deg); clockwise to '
      '-190 deg; 17 px wide; 1024x768; MJPG AVI',
      'uneven illumination and background texture',
      W=1024, H=768, um=350 / 17, heading=180.0,
      tube=dict(od_um=350, L_um=9000, sections=[dict(frac=1.0)]),
      holder=dict(kind='capillary', Rg=1.4, Rb=1.08),
      field=dict(vignette=0.6, gradient=(0.35, -0.2), texture=0.06, vignette_centre=(0.08, -0.05)),
      bends=ease(28, 0, -190), format=dict(kind='avi_mjpg', quality=85)),
    S('tilted_focus_halo_ffv1',
      'water-filled tube; the specimen plane is tilted against the focal plane: in focus in the '
      'middle of the frame, '
      'out of focus toward the left and right edges with opposite signs (Becke-line halo bright '
      'outside the tube on one side, dark on the other; blur up to ~3.5 px); glass capillary from the '
      'left; CCW to 200 deg; 15 px wide; 800x600; FFV1 AVI',
      'defocus and halo varying along the tube and with the bend',
      W=800, H=600, um=20.0, heading=0.0,
      tube=dict(od_um=300, L_um=9000, n_lumen=N_WATER, sections=[dict(frac=1.0)]),
      holder=dict(kind='capillary', Rg=1.5, Rb=1.1), look='tie',
      optics=dict(NA=0.09, NA_c=0.3, psf=1.0, tie=dict(z0=0.0, zx=7.0, zy=0.0, blur_per_z=0.8, k=1.2,
                                              lap_sigma=2.2)),
      bends=ease(28, 0, 200), format=dict(kind='avi_ffv1'), cost=1.5),
    S('dust_bubbles_fibre_mjpg',
      'clutter: dust on the camera sensor (fixed soft rings), three air bubbles in the water (dark '
      'rings with a bright centre), and a hair lying in the dish right across the field, which the '
      'tube bends over; thin pipette from the left; CCW to 180 deg; 16 px wide; 800x600; MJPG AVI',
      'non-tube structures: a long thin curved fibre crossing the tube, round bubbles, sensor dust',
      W=800, H=600, um=20.0, heading=0.0,
      tube=dict(od_um=320, L_um=9000, sections=[dict(frac=1.0)]),
      holder=dict(kind='pipette', Rg=0.65, Rb=0.3, slope=0.03), optics=dict(NA=0.08, NA_c=0.2),
      field=dict(dust=9, bubbles=[(650.0, 520.0, 22.0), (120.0, 90.0, 14.0), (700.0, 110.0, 9.0)],
                 fibres=[((-20.0, 330.0), 28.0, [300.0, 300.0, 350.0], [0.0012, -0.002, 0.001],
                          1.3, 0.35)]),
      bends=ease(28, 0, 180), format=dict(kind='avi_mjpg', quality=88)),
    S('drift_shake_flicker_ffv1',
      'stage drift (0.3, -0.15 px/frame: 12 px over the video) with camera shake (0.25 px rms) '
      'moving specimen, holder and dish texture together, and lamp flicker (+-8 %); thin pipette '
      'from the bottom-right corner (tube heading 140 deg); CCW to 200 deg; 14 px wide; 640x480; '
      '40 frames; FFV1 AVI',
      'moving base and holder; brightness changing frame to frame',
      W=640, H=480, um=300 / 14, heading=140.0,
      tube=dict(od_um=300, L_um=8500, sections=[dict(frac=1.0)]),
      holder=dict(kind='pipette', Rg=0.6, Rb=0.3, slope=0.03),
      field=dict(drift=(0.3, -0.15), shake=0.25, flicker=(0.08, 3.3), texture=0.04),
      bends=hold(ease(36, 0, 200), 4), format=dict(kind='avi_ffv1'), cost=2),
    S('rgb_halogen_chroma_tifstack',
      'colour frames: halogen lamp, blue-dyed tube (absorbs red), lateral chromatic aberration '
      '(red 0.06 % larger, blue 0.06 % smaller) and axial colour (red and blue more blurred); '
      'dark clamp from the left at 8 deg; CCW to 240 deg; 17 px wide; 896x672; 24 frames; RGB '
      'multi-page TIFF (deflate)',
      'chromatic colour frames (edges differ by channel); clamp',
      W=896, H=672, um=22.0, heading=8.0, optics=dict(NA=0.08, NA_c=0.3),
      tube=dict(od_um=380, L_um=10000, dye=0.9, sections=[dict(frac=0.5, ratio=0.9),
                                                          dict(frac=0.5, ratio=1.1)]),
      holder=dict(kind='clamp', half_w=4.5, trans=0.05),
      colour=dict(lamp=[1.0, 0.82, 0.55], dye=[1.0, 0.55, 0.08], lateral=6e-4, psf=[1.4, 1.0, 1.7]),
      bends=ease(24, 0, 240), format=dict(kind='tif_stack', compression='zlib'), cost=1.5),
]


# ----------------------------------------------------------------------------- self-checks
def _natkey(s):
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r'(\d+)', s)]


def read_back(path):
    """The frames as a reader would get them (natural order for folders), as float grey."""
    frames = []
    if os.path.isdir(path):
        for fn in sorted(os.listdir(path), key=_natkey):
            q = os.path.join(path, fn)
            im = tifffile.imread(q) if q.endswith('.tif') else cv2.imread(q, cv2.IMREAD_UNCHANGED)
            frames.append(im)
    elif path.endswith('.tif'):
        a = tifffile.imread(path)
        frames = list(a)
    else:
        cap = cv2.VideoCapture(path)
        while True:
            ok, im = cap.read()
            if not ok:
                break
            frames.append(im)
    return frames


def _grey(im):
    im = im.astype(np.float64)
    if im.ndim == 3:
        im = im[..., :3].mean(2)
    return im


def check_conventions():
    lines = []
    lat = lattice(5)
    oo = dict(n_m=N_WATER, a_o=1.5, a_c=0.01)          # no refraction loss: pure coverage
    for row in (100.0, 100.25):
        cv = Curve((-40.0, -row), 0.0, [300.0], [0.0])
        b = Body(cv, 0.0, 300.0, lambda s: np.full_like(s, 6.0), mu=50.0, n_b=N_WATER)
        lay = Layered(body_layers(b, oo, lat, (260, 300)), 25)
        T, _, _ = lay.pixel_values([1.0])
        cov = np.zeros(260 * 300)
        cov[lay.ids] = 1 - T[0]
        cov = cov.reshape(260, 300)[PAD:, PAD:]
        rows = np.arange(cov.shape[0])[:, None]
        cen = (cov[:, 20:200] * rows).sum(0) / cov[:, 20:200].sum(0)
        wid = cov[:, 20:200].sum(0)
        lines.append('rod on row %.2f: coverage centroid %.5f .. %.5f, width %.4f .. %.4f (12 px)'
                     % (row, cen.min(), cen.max(), wid.min(), wid.max()))
    cv = Curve((0.0, 0.0), 0.0, [100.0], [math.pi / 2 / 100])
    p = cv.points(np.array([100.0]))[0]
    lines.append('sign: +90 deg over 100 px from (0,0) heading +x ends at (%.5f, %.5f) (y up), '
                 'heading %.4f deg' % (p[0], p[1], math.degrees(cv.th1)))
    return lines


def check_scene(sc0):
    """Truth against itself, against an independent integration, the renderer's geometry
    against the truth, and the frames on disk."""
    from scipy.integrate import solve_ivp
    from scipy.spatial import cKDTree
    sc = prepare(dict(sc0))
    name = sc['name']
    d = os.path.join(SCENES_DIR, name)
    meta = json.load(open(os.path.join(d, 'scene.json')))
    um = meta['um_per_px']
    tr = np.genfromtxt(os.path.join(d, 'truth_tracks.csv'), delimiter=',', names=True,
                       dtype=None, encoding=None)
    cl = np.loadtxt(os.path.join(d, 'truth_centrelines.csv'), delimiter=',', skiprows=1)
    ro0, ri, ros, e = radii(sc)
    offs = frame_offsets(sc)
    res = dict(name=name, bend=0.0, length=0.0, spacing=0.0, ends=0.0, integ=0.0, foot=0.0,
               holder=0.0, margin=1e9)
    lens = sc['_lens']
    starts = np.concatenate([[0], np.cumsum(lens)])
    for f in range(sc['n']):
        pts = cl[cl[:, 0] == f]
        s, P = pts[:, 1] / um, pts[:, 2:4] / um
        seg = np.diff(P, axis=0)
        ang = np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))
        res['bend'] = max(res['bend'], abs(math.degrees(ang[-1] - ang[0]) - tr['bend_angle_deg'][f]))
        Lp = np.hypot(*seg.T).sum()
        res['length'] = max(res['length'], abs(Lp - tr['length_um'][f] / um))
        res['spacing'] = max(res['spacing'], np.hypot(*seg.T).max())
        res['ends'] = max(res['ends'], np.hypot(*(P[0] - [tr['base_x_um'][f] / um, tr['base_y_um'][f] / um])),
                          np.hypot(*(P[-1] - [tr['tip_x_um'][f] / um, tr['tip_y_um'][f] / um])))
        # independent integration of x' = cos th, y' = sin th, th' = kappa(s)
        kap = sc['_kap'][f]
        bx, by = sc['base']
        y0 = [bx + offs[f][0], -(by + offs[f][1]), math.radians(sc['heading'])]

        def rhs(t, y):
            i = min(np.searchsorted(starts, t, 'right') - 1, len(kap) - 1)
            return [math.cos(y[2]), math.sin(y[2]), kap[i]]
        sol = solve_ivp(rhs, (0, s[-1]), y0, t_eval=s, rtol=1e-11, atol=1e-11, method='DOP853',
                        max_step=0.5)
        res['integ'] = max(res['integ'], np.hypot(sol.y[0] - P[:, 0], sol.y[1] - P[:, 1]).max())
        # the renderer's base is the holder's end face
        if sc.get('holder'):
            hb = holder_bodies(sc, tuple(offs[f]))[0]
            res['holder'] = max(res['holder'], float(np.hypot(*(hb.curve.pc[0, 2:4] - P[0]))))
        col, row = P[:, 0], -P[:, 1]
        W, H = sc['W'], sc['H']
        r = ros.max()
        m = np.minimum.reduce([col + 0.5 - r, W - 0.5 - col - r, row + 0.5 - r, H - 0.5 - row - r])
        if sc.get('border'):
            m = m[s > 3 * r]
        res['margin'] = min(res['margin'], float(m.min()))
    # the renderer's foot points against brute force on the truth polyline (frames 0, mid, last)
    rng = np.random.default_rng(1)
    for f in sorted({0, sc['n'] // 2, sc['n'] - 1}):
        pts = cl[cl[:, 0] == f]
        P = pts[:, 2:4] / um
        cv = tube_curve(sc, f, tuple(offs[f]))
        i = rng.integers(0, len(P), 400)
        th = rng.uniform(0, 2 * np.pi, 400)
        rad = rng.uniform(0, 1.2 * r, 400)
        Q = P[i] + np.stack([rad * np.cos(th), rad * np.sin(th)], 1)
        tree = cKDTree(P)
        _, nn = tree.query(Q, k=8)
        best = np.full(len(Q), np.inf)
        for j in range(8):
            for sg in (np.clip(nn[:, j] - 1, 0, len(P) - 2), np.clip(nn[:, j], 0, len(P) - 2)):
                A, B = P[sg], P[sg + 1]
                AB = B - A
                t = np.clip(((Q - A) * AB).sum(1) / (AB ** 2).sum(1), 0, 1)
                best = np.minimum(best, np.hypot(*(Q - A - t[:, None] * AB).T))
        ren = np.full(len(Q), np.inf)
        for pc in cv.pc:
            u, dd = foot(pc, Q[:, 0], Q[:, 1])
            sp = pc[0] + u
            ok = (u >= -1e-9) & (u <= pc[1] + 1e-9) & (sp >= 0) & (sp <= cv.s1)
            ren = np.where(ok, np.minimum(ren, np.abs(dd)), ren)
        far_ends = np.minimum(np.hypot(*(Q - P[0]).T), np.hypot(*(Q - P[-1]).T)) > 1.5 * r
        inside = (best < 0.9 * r) & far_ends   # where the nearest point is a perpendicular foot
        res['foot'] = max(res['foot'], float(np.abs(ren[inside] - best[inside]).max()))
    # frames on disk
    frames = read_back(os.path.join(d, meta['input']))
    res['n_read'] = len(frames)
    res['size'] = list(frames[0].shape)
    bad = 0
    n = len(frames)
    core, body = [], []          # +-0.6 r about the truth centreline, and the body + 2 px
    for f in range(min(n, sc['n'])):
        pts = cl[cl[:, 0] == f]
        cp = np.round(np.stack([pts[:, 2] / um, -pts[:, 3] / um], 1) * 16).astype(np.int32)
        for lst, th in ((core, max(1, int(1.2 * r))), (body, int(2 * r + 5))):
            mk = np.zeros((sc['H'], sc['W']), np.uint8)
            cv2.polylines(mk, [cp], False, 1, thickness=th, shift=4)
            lst.append(mk.astype(bool))
    for f in range(min(n, sc['n'])):
        g = _grey(frames[f])
        bg = np.median(g)
        for j in (f - 1, f + 1):
            if 0 <= j < len(core):
                other = core[j] & ~body[f]     # where frame j's tube is and this one's is not
                own = core[f] & ~body[j]
                if other.sum() < 20 or own.sum() < 20:
                    continue
                if np.abs(g[other] - bg).mean() > np.abs(g[own] - bg).mean():
                    bad += 1
    res['order_bad'] = bad
    ok = (res['bend'] < 0.05 and res['length'] < 0.05 and res['spacing'] <= 0.33 + 1e-9
          and res['ends'] < 1e-6 and res['integ'] < 1e-4 and res['foot'] < 0.01
          and res['holder'] < 1e-6 and res['n_read'] == sc['n'] and bad == 0
          and (res['margin'] >= 6 or sc.get('border')))
    res['ok'] = bool(ok)
    return res


def run_checks(scenes, jobs):
    lines = ['alien8 render.py --check', ''] + check_conventions() + ['']
    head = ('%-34s %8s %8s %7s %8s %8s %8s %7s %7s %5s %5s %s'
            % ('scene', 'bend deg', 'len px', 'dS px', 'ends px', 'integ px', 'foot px', 'margin',
               'frames', 'order', 'ok', 'size'))
    lines += [head, '-' * len(head)]
    if jobs > 1:
        with Pool(jobs) as pool:
            rs = pool.map(check_scene, scenes)
    else:
        rs = [check_scene(s) for s in scenes]
    for r in rs:
        lines.append('%-34s %8.4f %8.4f %7.3f %8.1e %8.1e %8.1e %7.1f %7d %5d %5s %s'
                     % (r['name'], r['bend'], r['length'], r['spacing'], r['ends'], r['integ'],
                        r['foot'], r['margin'], r['n_read'], r['order_bad'],
                        'yes' if r['ok'] else 'NO', 'x'.join(map(str, r['size']))))
    lines.append('')
    lines.append('%d/%d scenes pass' % (sum(r['ok'] for r in rs), len(rs)))
    txt = '\n'.join(lines)
    print(txt)
    return txt


# ----------------------------------------------------------------------------- CLI
def _render_one(sc):
    try:
        dt = render_scene(sc)
        return sc['name'], dt, None
    except Exception:  # noqa: BLE001
        import traceback
        return sc['name'], 0.0, traceback.format_exc()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('-j', type=int, default=1)
    ap.add_argument('--only', nargs='*')
    ap.add_argument('--list', action='store_true')
    ap.add_argument('--plan', action='store_true', help='geometry only: margins, crossings')
    ap.add_argument('--check', action='store_true',
                    help='self-checks of the rendered scenes (truth, geometry, files)')
    a = ap.parse_args(argv)
    scenes = SCENES
    if a.only:
        names = {s['name'] for s in scenes}
        bad = set(a.only) - names
        if bad:
            sys.exit('unknown scene(s): ' + ', '.join(sorted(bad)))
        scenes = [s for s in scenes if s['name'] in a.only]
    if a.list:
        for s in scenes:
            print('%-34s %s' % (s['name'], s['description']))
        return
    if a.plan:
        for s in scenes:
            sc = prepare(dict(s))
            r = plan(sc)
            print('%-32s n=%3d bend %7.1f..%7.1f  base=(%.1f,%.1f) margin %6.1f  kr %.2f  '
                  'minsep %.2f  self %s  touch %s  holder %s'
                  % (sc['name'], sc['n'], min(sc['bends']), max(sc['bends']), sc['base'][0],
                     sc['base'][1], r['margin'], r['max_kr'], r['min_sep'],
                     _rng(r['self_cross']), _rng(r['self_touch']), _rng(r['holder_cross'])))
        return
    if a.check:
        run_checks(scenes, a.j)
        return
    os.makedirs(SCENES_DIR, exist_ok=True)
    t0 = time.time()
    order = sorted(scenes, key=lambda s: -s.get('cost', 1.0))
    if a.j > 1:
        with Pool(a.j) as pool:
            res = pool.imap_unordered(_render_one, order)
            for name, dt, err in res:
                print('  %-34s %6.1fs%s' % (name, dt, ('\n' + err) if err else ''), flush=True)
    else:
        for s in order:
            name, dt, err = _render_one(s)
            print('  %-34s %6.1fs%s' % (name, dt, ('\n' + err) if err else ''), flush=True)
    print('rendered %d scenes in %.0f s' % (len(order), time.time() - t0))


def _rng(lst):
    if not lst:
        return '-'
    return '%d-%d(%d)' % (lst[0], lst[-1], len(lst))


if __name__ == '__main__':
    main()

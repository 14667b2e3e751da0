#!/usr/bin/env python
"""alien7 -- an independent synthetic evaluation set for a microscope-video tube tracker.

    python render.py [-j 2] [--only NAME ...]   # render scenes into scenes/<name>/
    python render.py --list                    # list the scenes
    python render.py --plan [--only NAME ...]  # geometry only: margins, curvature, crossings
    python render.py --check [--only NAME ...] # self-checks of the rendered scenes -> check_report.txt

Written from the subject's physics, apart from the tracker and from the other renderers
(alien4/5/6). Geometry is in pixels in a math frame X = col, Y = -row (y up). Every frame's
centreline is defined by its heading theta(s) (an analytic function, or for the loaded tube
a cubic spline solved from a beam equation); positions are integrated with 6-point
Gauss-Legendre quadrature per 0.2 px interval, so the truth is exact to ~1e-9 px.
"""
import argparse
import hashlib
import json
import math
import os
import shutil
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import cv2
import numpy as np
import tifffile
from PIL import Image
from scipy import ndimage
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES_DIR = os.path.join(HERE, 'scenes')
MARGIN = 16          # the canvas is this much larger on every side; cropped after the blur
H_VERT = 0.2         # vertex spacing of the rendering polyline (px)
TRUTH_DS = 0.33      # truth centreline spacing (px), <= 0.35
END_EPS = 0.002      # extra truth points this far (px) from base and tip (end tangents)
GLN, GLW = np.polynomial.legendre.leggauss(6)

CONVENTIONS = {
    'pixels': 'pixel (col,row) has its centre at (col,row); x_um = col*um_per_px, y_um = -row*um_per_px (y up)',
    'bend_angle_deg': 'unwrapped CCW rotation of the tip tangent relative to the base tangent, both pointing '
                      'base->tip; clockwise negative',
    'base': 'where the tube leaves its holder (the glass end face or the clamp face); with no holder, where '
            'the centreline crosses the outer pixel edge of the border (row -0.5 etc.); the tube is straight '
            'behind the base',
    'tip': 'apex of the closed hemispherical cap (radius = outer radius at the tip; half-width '
           'sqrt(Rc^2-(s-(L-Rc))^2) over the last Rc of arc, following the centreline)',
    'length_um': 'arc length base -> tip',
    'truth_centrelines': 'points exact on the curve, uniform in s with spacing <= 0.33 px, plus one extra '
                         'point 0.002 px from each end; first = base, last = tip',
    'flip': 'for mirrored scenes the image and the truth are both flipped (col -> W-1-col and/or '
            'row -> H-1-row); one flip reverses the sign of the bend',
}


# ----------------------------------------------------------------------------- profiles

def prof_fns(kind, p=()):
    """Normalised curvature profile f(t) on t = s/L in [0,1] with F(t) = int_0^t f, F(1) = 1."""
    if kind == 'uniform':
        return (lambda t: np.ones_like(t)), (lambda t: np.asarray(t, float))
    if kind == 'ramp':                       # f ~ a + (b-a) t
        a, b = p
        m = (a + b) / 2.0
        return (lambda t: (a + (b - a) * t) / m), (lambda t: (a * t + (b - a) * t * t / 2) / m)
    if kind == 'power':                      # f ~ c + t^q  (stiff base)
        c, q = p
        m = c + 1.0 / (q + 1)
        return (lambda t: (c + np.clip(t, 0, 1) ** q) / m), \
               (lambda t: (c * t + np.clip(t, 0, 1) ** (q + 1) / (q + 1)) / m)
    if kind == 'rpower':                     # f ~ c + (1-t)^q  (stiff tip)
        c, q = p
        m = c + 1.0 / (q + 1)
        return (lambda t: (c + np.clip(1 - t, 0, 1) ** q) / m), \
               (lambda t: (c * t + (1 - np.clip(1 - t, 0, 1) ** (q + 1)) / (q + 1)) / m)
    if kind == 'bump':                       # f ~ sin^2 on [t1,t2], 0 elsewhere (straight ends)
        t1, t2 = p
        w = t2 - t1

        def f(t):
            u = np.clip((t - t1) / w, 0, 1)
            return 2 * np.sin(np.pi * u) ** 2 / w

        def F(t):
            u = np.clip((t - t1) / w, 0, 1)
            return u - np.sin(2 * np.pi * u) / (2 * np.pi)
        return f, F
    raise ValueError(kind)


def ease(t):
    t = np.clip(t, 0, 1)
    return t * t * (3 - 2 * t)


# ----------------------------------------------------------------------------- curve

class Curve:
    """Centreline s in [0,L] (px) from heading hfun(s) -> (theta, kappa); straight behind the base."""

    def __init__(self, hfun, L, x0, y0, ext):
        self.hfun, self.L = hfun, float(L)
        self.N = max(4, int(math.ceil(L / H_VERT)))
        self.h = self.L / self.N
        s = np.arange(self.N + 1) * self.h
        th, ka = hfun(s)
        dx, dy = self._gl(s[:-1], np.full(self.N, self.h))
        self.Xn = x0 + np.concatenate([[0.0], np.cumsum(dx)])
        self.Yn = y0 + np.concatenate([[0.0], np.cumsum(dy)])
        self.th0 = float(th[0])
        self.thL = float(th[-1])
        ne = int(math.ceil(ext / self.h)) if ext > 0 else 0
        se = -np.arange(ne, 0, -1) * self.h
        self.s = np.concatenate([se, s])
        self.X = np.concatenate([x0 + se * math.cos(self.th0), self.Xn])
        self.Y = np.concatenate([y0 + se * math.sin(self.th0), self.Yn])
        self.th = np.concatenate([np.full(ne, self.th0), th])
        self.ka = np.concatenate([np.zeros(ne), ka])

    def _gl(self, a, ds):
        m = a[:, None] + (GLN[None, :] + 1) / 2 * ds[:, None]
        th, _ = self.hfun(m.ravel())
        th = th.reshape(m.shape)
        return (np.cos(th) * GLW).sum(1) * ds / 2, (np.sin(th) * GLW).sum(1) * ds / 2

    def pos(self, sq):
        sq = np.asarray(sq, float)
        k = np.clip(np.floor(sq / self.h).astype(int), 0, self.N - 1)
        a = k * self.h
        dx, dy = self._gl(a, sq - a)
        return self.Xn[k] + dx, self.Yn[k] + dy

    def theta(self, sq):
        return self.hfun(np.asarray(sq, float))[0]


def straight_curve(x0, y0, th0, L):
    return Curve(lambda s: (np.full_like(s, th0), np.zeros_like(s)), L, x0, y0, 0.0)


# ----------------------------------------------------------------------------- tube body

class Chunk:
    pass


class Tube:
    """A tube body around a Curve: outer radius ro(s), lumen ri(s) offset e (in-plane, left normal)."""

    def __init__(self, curve, ro0, ro1, idf, e, opt, cap=True, s_lo=-1e18, actuator=True):
        self.c, self.L = curve, curve.L
        self.ro0, self.ro1, self.idf, self.e = ro0, ro1, idf, e
        self.cap, self.s_lo, self.actuator = cap, s_lo, actuator
        self.s_hi = self.L
        self.opt = opt
        self.ro_max = max(ro0, ro1) + abs(e) * 0
        self._chunks()

    def geom(self, s):
        Rc = self.ro1 if self.cap else 0.0
        sc = self.L - Rc
        t = np.clip(s / sc, 0.0, 1.0)
        ro_l = self.ro0 + (self.ro1 - self.ro0) * t
        ri_l = self.idf * ro_l
        if not self.cap:
            return ro_l, ri_l, np.zeros_like(s)
        u = s - sc
        inc = u > 0
        ro = np.where(inc, np.sqrt(np.maximum(Rc * Rc - u * u, 0.0)), ro_l)
        ric = self.idf * Rc
        ri = np.where(inc, np.sqrt(np.maximum(ric * ric - u * u, 0.0)), ri_l)
        return ro, ri, np.where(inc, u, 0.0)

    def _chunks(self):
        c = self.c
        s, th = c.s, c.th
        n = len(s)
        target = max(10.0, 1.2 * self.ro_max)
        starts = [0]
        i = 0
        while True:
            j = int(np.searchsorted(s, s[i] + target))
            j = min(j, n - 1)
            turn = np.abs(th[i:j + 1] - th[i])
            over = np.nonzero(turn > 0.5)[0]
            if len(over):
                j = i + max(int(over[0]), 3)
            if j >= n - 2:
                break
            starts.append(j)
            i = j
        starts.append(n - 1)
        pad = 8
        R = self.ro_max + 1.5
        self.chunks = []
        for k in range(len(starts) - 1):
            i0, i1 = starts[k], starts[k + 1]
            ch = Chunk()
            ch.a = -1e18 if k == 0 else s[i0]
            ch.b = 1e18 if k == len(starts) - 2 else s[i1]
            ch.lo, ch.hi = max(0, i0 - pad), min(n, i1 + pad + 1)
            ch.mid = (i0 + i1) // 2
            xs, ys = c.X[i0:i1 + 1], c.Y[i0:i1 + 1]
            ch.box = (xs.min() - R, xs.max() + R, ys.min() - R, ys.max() + R)
            self.chunks.append(ch)

    def _arc(self, i, X, Y):
        c = self.c
        tx, ty = np.cos(c.th[i]), np.sin(c.th[i])
        qx, qy = X - c.X[i], Y - c.Y[i]
        u = qx * tx + qy * ty
        w = -qx * ty + qy * tx
        k = c.ka[i]
        small = np.abs(k) < 1e-12
        if not small.any():
            return c.s[i] + np.arctan2(k * u, 1 - k * w) / k, (1 - np.hypot(k * u, 1 - k * w)) / k
        if small.all():
            return c.s[i] + u, w
        ks = np.where(small, 1.0, k)
        ds = np.where(small, u, np.arctan2(ks * u, 1 - ks * w) / ks)
        d = np.where(small, w, (1 - np.hypot(ks * u, 1 - ks * w)) / ks)
        return c.s[i] + ds, d

    def foot(self, ch, X, Y):
        """Foot point (arc length s, signed normal offset d, + to the left) of points on this chunk:
        local osculating-arc projection at the nearest vertex, found by iterating from the chunk middle."""
        c = self.c
        i = np.full(len(X), ch.mid)
        s0, h = c.s[0], c.h
        s, _ = self._arc(i, X, Y)
        i = np.clip(np.rint((s - s0) / h).astype(np.int64), ch.lo, ch.hi - 1)
        return self._arc(i, X, Y)

    def candidates(self, W, H):
        """Per chunk: pixel (col,row) arrays that may hold samples inside this chunk's body."""
        out = []
        for ch in self.chunks:
            x0, x1, y0, y1 = ch.box
            c0, c1 = max(int(math.floor(x0)), -MARGIN), min(int(math.ceil(x1)), W + MARGIN - 1)
            r0, r1 = max(int(math.floor(-y1)), -MARGIN), min(int(math.ceil(-y0)), H + MARGIN - 1)
            if c1 < c0 or r1 < r0:
                out.append(None)
                continue
            cc, rr = np.meshgrid(np.arange(c0, c1 + 1), np.arange(r0, r1 + 1))
            cc, rr = cc.ravel(), rr.ravel()
            s, d = self.foot(ch, cc.astype(float), -rr.astype(float))
            keep = ((s >= ch.a - 2.0) & (s < ch.b + 2.0) & (s >= self.s_lo - 2.0) & (s <= self.s_hi + 2.0)
                    & (np.abs(d) < self.ro_max + 1.0))
            out.append((cc[keep], rr[keep]) if keep.any() else None)
        return out

    def layer(self, ch, X, Y, acc, idx):
        s, d = self.foot(ch, X, Y)
        ro, ri, uc = self.geom(s)
        inr = (s >= ch.a) & (s < ch.b) & (s >= self.s_lo - 0.5) & (s <= self.s_hi + 0.5)
        ad = np.abs(d)
        nb = inr & ((np.abs(ad - ro) < 0.4) | (np.abs(np.abs(d - self.e) - ri) < 0.4) | (np.abs(s) < 0.4)
                    | ((s > self.L - self.ro1 - 0.5) & (ad < self.ro_max + 0.5))
                    | (np.abs(s - self.s_lo) < 0.5) | (np.abs(s - self.s_hi) < 0.5))
        acc['NB'][idx[nb]] = 1.0
        ok = inr & (s >= self.s_lo) & (s <= self.s_hi) & (ad < ro)
        if not ok.any():
            return
        s, d, ro, ri, uc, idx = s[ok], d[ok], ro[ok], ri[ok], uc[ok], idx[ok]
        # boundary code: samples of one pixel with different codes straddle a discontinuity
        acc['B'][idx] += 1.0 + 7.0 * ((d - self.e) ** 2 < ri * ri) + 3001.0 * (s >= 0)
        o = self.opt
        d2 = np.maximum(ro * ro - d * d, 1e-9)
        co = 2 * np.sqrt(d2)
        dl = d - self.e
        l2 = ri * ri - dl * dl
        inl = l2 > 0
        l2p = np.maximum(l2, 1e-9)
        cl = np.where(inl, 2 * np.sqrt(l2p), 0.0)
        wall = np.maximum(co - cl, 0.0)
        go = 2 * np.sqrt(d * d + uc * uc) / np.sqrt(d2)
        gi = np.where(inl, 2 * np.sqrt(dl * dl + uc * uc) / np.sqrt(l2p), 0.0)
        dno = np.where(s < 0, o['dn_o_in'], o['dn_o'])
        xo = (dno * go / o['NA']) ** 2
        xi = (o['dn_i'] * gi / o['NA']) ** 2
        p2 = o['rimp'] / 2.0
        rm = o['rim_max']
        acc['A'][idx] += o['mu_w'] * wall + o['mu_l'] * cl
        yo, yi = xo ** p2, xi ** p2
        acc['LT'][idx] += np.log1p(-rm * yo / (1 + yo)) + np.where(inl, np.log1p(-rm * yi / (1 + yi)), 0.0)
        acc['OPL'][idx] += o['dn_o'] * co + o['dn_i'] * cl
        acc['EM'][idx] += wall
        acc['DF'][idx] += xo / (1 + xo) + np.where(inl, o['df_lumen'] * xi / (1 + xi), 0.0)
        acc['LENS'][idx] += o['lens'] * np.exp(-(d / (0.35 * np.maximum(ro, 1e-6))) ** 2)
        if self.actuator:
            acc['INS'][idx] += (s >= 0)


class Holder:
    """Glass pipette / capillary (exact chords of outer and bore circles) or an opaque clamp."""

    def __init__(self, kind, bx, by, th0, Lh, Rg0, slope, bore, bore_frac, hw, opt):
        self.kind, self.bx, self.by, self.th0, self.Lh = kind, bx, by, th0, Lh
        self.Rg0, self.slope, self.bore, self.bore_frac, self.hw = Rg0, slope, bore, bore_frac, hw
        self.opt = opt
        self.tx, self.ty = math.cos(th0), math.sin(th0)
        self.Rmax = hw if kind == 'clamp' else Rg0 + slope * Lh

    def uv(self, X, Y):
        qx, qy = X - self.bx, Y - self.by
        return qx * self.tx + qy * self.ty, -qx * self.ty + qy * self.tx

    def candidates(self, W, H):
        pts = []
        for u in (0.0, -self.Lh):
            for v in (-self.Rmax - 2, self.Rmax + 2):
                pts.append((self.bx + u * self.tx - v * self.ty, self.by + u * self.ty + v * self.tx))
        pts = np.array(pts)
        c0, c1 = max(int(math.floor(pts[:, 0].min())) - 2, -MARGIN), \
            min(int(math.ceil(pts[:, 0].max())) + 2, W + MARGIN - 1)
        r0, r1 = max(int(math.floor(-pts[:, 1].max())) - 2, -MARGIN), \
            min(int(math.ceil(-pts[:, 1].min())) + 2, H + MARGIN - 1)
        if c1 < c0 or r1 < r0:
            return None
        cc, rr = np.meshgrid(np.arange(c0, c1 + 1), np.arange(r0, r1 + 1))
        cc, rr = cc.ravel(), rr.ravel()
        u, v = self.uv(cc.astype(float), -rr.astype(float))
        R = self.hw if self.kind == 'clamp' else self.Rg0 + self.slope * np.maximum(-u, 0)
        keep = (u < 1.0) & (u > -self.Lh - 1.0) & (np.abs(v) < R + 1.5)
        return (cc[keep], rr[keep]) if keep.any() else None

    def radii(self, u):
        Ro = self.Rg0 + self.slope * np.maximum(-u, 0.0)
        Ri = np.maximum(self.bore, self.bore_frac * Ro)
        return Ro, Ri

    def layer(self, X, Y, acc, idx):
        u, v = self.uv(X, Y)
        inH = (u < 0) & (u > -self.Lh)
        o = self.opt
        Ro, Ri = self.radii(u)
        av = np.abs(v)
        Rb = self.hw if self.kind == 'clamp' else Ro
        nb = (((np.abs(u) < 0.5) | (np.abs(u + o['face_w']) < 0.5)) & (av < Rb + 0.5)) | \
            ((u < 0.5) & (u > -self.Lh - 0.5) & ((np.abs(av - Rb) < 0.5) | (np.abs(av - Ri) < 0.5)))
        acc['NB'][idx[nb]] = 1.0
        if self.kind == 'clamp':
            c = inH & (np.abs(v) < self.hw)
            acc['B'][idx[c]] += 1000.0
            acc['OCC'][idx[c]] += 1.0
            acc['HOLD'][idx[c]] += 1.0
            return
        g = inH & (np.abs(v) < Ro)
        if not g.any():
            return
        u, v, Ro, Ri, idx = u[g], v[g], Ro[g], Ri[g], idx[g]
        d2o = np.maximum(Ro * Ro - v * v, 1e-9)
        co = 2 * np.sqrt(d2o)
        d2i = Ri * Ri - v * v
        inb = d2i > 0
        d2ip = np.maximum(d2i, 1e-9)
        cb = np.where(inb, 2 * np.sqrt(d2ip), 0.0)
        cg = co - cb
        go = 2 * np.abs(v) / np.sqrt(d2o)
        gi = np.where(inb, 2 * np.abs(v) / np.sqrt(d2ip), 0.0)
        xo = (o['dn_g'] * go / o['NA']) ** 2
        xi = (o['dn_gb'] * gi / o['NA']) ** 2
        p2 = o['rimp_g'] / 2.0
        face = (u > -o['face_w']) & ~inb
        acc['B'][idx] += 31.0 + 127.0 * inb + 500.0 * face
        acc['A'][idx] += o['mu_g'] * cg
        acc['LT'][idx] -= np.log1p(xo ** p2) + np.where(inb, np.log1p(xi ** p2), 0.0) + face * o['face_s']
        acc['OPL'][idx] += o['dn_g'] * cg
        acc['EM'][idx] += o['glass_glow'] * cg
        acc['DF'][idx] += xo / (1 + xo) + np.where(inb, xi / (1 + xi), 0.0) + face * 0.5
        acc['HOLD'][idx] += 1.0


CHANNELS = ('A', 'LT', 'OPL', 'EM', 'DF', 'LENS', 'OCC', 'INS', 'HOLD', 'B', 'NB')


def nrooks(S):
    i, j = np.meshgrid(np.arange(S), np.arange(S), indexing='ij')
    ox = (i * S + j + 0.5) / (S * S) - 0.5
    oy = (j * S + i + 0.5) / (S * S) - 0.5
    return np.stack([ox.ravel(), oy.ravel()], 1)


def fibonacci88():
    """The 89-point Fibonacci lattice (generator 55) in the pixel without its centre point: 88 samples,
    point-symmetric about the pixel centre and none at it (an edge through a pixel centre is split
    evenly), 88 distinct offsets along the rows, the columns and both diagonals, and a small worst-case
    coverage error for a straight edge in any direction (RMS over edge positions <= 0.025)."""
    N, g = 89, 55
    i = np.arange(N)
    p = np.stack([(i + 0.5) / N - 0.5, ((i * g + g / 2.0) / N) % 1.0 - 0.5], 1)
    return p[np.abs(p).sum(1) > 1e-12]


OFF16, OFFR = nrooks(4), fibonacci88()


def sample_values(acc, look, K):
    """Per-sample look value (for the refinement test) and the channels to average per pixel."""
    n = acc['A'].size // K
    sh = (n, K)
    occ = np.minimum(acc['OCC'], 1.0).reshape(sh)
    kind = look['kind']
    if kind in ('bf', 'phase'):
        t = np.exp(-acc['A'] + acc['LT'] * (1.0 if kind == 'bf' else look.get('phase_rim', 0.3))).reshape(sh)
        t = t * (1 + acc['LENS'].reshape(sh))
        t = t * (1 - occ) + occ * look.get('clamp_T', 0.06)
        if kind == 'bf':
            return t, {'T': t}
        opl = acc['OPL'].reshape(sh) * look['kph']
        return t + opl, {'T': t, 'OPL': acc['OPL'].reshape(sh)}
    if kind == 'df':
        v = (1 - np.exp(-1.3 * acc['DF'])).reshape(sh) * (1 - occ)
        return v, {'DF': v}
    if kind == 'fluor':
        v = acc['EM'].reshape(sh) * look['kf'] * (1 - occ)
        return v, {'EM': v}
    if kind == 'mask':
        m = np.minimum(acc['INS'], 1.0).reshape(sh)
        hld = np.minimum(acc['HOLD'], 1.0).reshape(sh)
        return m + hld, {'M': m, 'H': hld}
    raise ValueError(kind)


def render_channels(tubes, holder, W, H, look):
    """Area-averaged per-pixel channels on the canvas: 16 N-rooks samples per pixel, 64 in pixels
    that straddle a discontinuity (outer surface, lumen, glass surfaces, end face, clamp, base)."""
    cw = W + 2 * MARGIN
    lists = []           # (obj, chunk or None, cols, rows)
    for t in tubes:
        for ch, cand in zip(t.chunks, t.candidates(W, H)):
            if cand is not None:
                lists.append((t, ch, cand[0], cand[1]))
    if holder is not None:
        cand = holder.candidates(W, H)
        if cand is not None:
            lists.append((holder, None, cand[0], cand[1]))
    if not lists:
        return {}, None
    lin_all = np.concatenate([(r + MARGIN) * cw + (c + MARGIN) for _, _, c, r in lists])
    act = np.unique(lin_all)
    act_c = act % cw - MARGIN
    act_r = act // cw - MARGIN
    maps = [np.searchsorted(act, (r + MARGIN) * cw + (c + MARGIN)) for _, _, c, r in lists]

    def run(sel_map, offs):
        K = len(offs)
        nsel = int(sel_map.max()) + 1 if sel_map is not None else len(act)
        acc = {k: np.zeros(nsel * K) for k in CHANNELS}
        for (obj, ch, _, _), m in zip(lists, maps):
            if sel_map is not None:
                loc = sel_map[m]
                keep = loc >= 0
                if not keep.any():
                    continue
                m2, loc = m[keep], loc[keep]
            else:
                m2, loc = m, m
            X = (act_c[m2][:, None] + offs[None, :, 0]).ravel()
            Y = (-(act_r[m2][:, None] + offs[None, :, 1])).ravel()
            idx = (loc[:, None] * K + np.arange(K)[None, :]).ravel()
            if ch is None:
                obj.layer(X, Y, acc, idx)
            else:
                obj.layer(ch, X, Y, acc, idx)
        v, ch = sample_values(acc, look, K)
        return acc['B'].reshape(-1, K), acc['NB'].reshape(-1, K), ch

    code, nb, chans = run(None, OFF16)
    means = {k: a.mean(1) for k, a in chans.items()}
    ref = np.nonzero((code.max(1) != code.min(1)) | (nb.max(1) > 0))[0]
    if len(ref):
        sel = np.full(len(act), -1)
        sel[ref] = np.arange(len(ref))
        _, _, chans2 = run(sel, OFFR)
        for k, a in chans2.items():
            means[k][ref] = a.mean(1)
    rr, cc = act_r + MARGIN, act_c + MARGIN
    return means, (rr, cc)


# ----------------------------------------------------------------------------- scenes

LOOK_BF = dict(kind='bf', dn_o=0.075, dn_o_in=0.03, dn_i=-0.41, NA=0.16, rimp=2.0, absorb=0.10,
               absorb_l=0.0, lens=0.10, df_lumen=1.0, dn_g=0.085, dn_gb=0.04, rimp_g=2.0, absorb_g=0.02,
               face_w=1.6, face_s=0.9, glass_glow=0.0, clamp_T=0.06, rim_max=1.0)

CAM = dict(fw=12000.0, read=6.0, bits=8, exposure=0.80, gamma=None, offset=0.0)


def scene_list():
    S = []

    def add(**kw):
        S.append(kw)

    # 1
    add(name='ramp_tipcurl_ffv1', W=640, H=480, um=21.875, n=30, fps=10.0,
        od=350.0, idf=0.6, ecc=0.25, L=9000.0, heading=0.0, base=(150.0, 396.0),
        prof=('ramp', (0.15, 1.85)), bend=[250 * ease(f / 27) for f in range(30)],
        holder=dict(kind='pipette', Rg=1.5, slope=0.015),
        fmt=dict(kind='ffv1'),
        desc='brightfield, thin glass pipette from the left; curvature ramps linearly along the tube '
             '(0.15 at the base to 1.85 at the tip, x mean): the tip curls 12x tighter than the base; '
             '0 -> 250 deg; 16 px wide; 640x480; FFV1 AVI',
        tests='centreline that is not a chain of arcs: curvature varying smoothly along the tube')
    # 2
    add(name='stiffbase_taper_png', W=800, H=600, um=20.0, n=28, fps=10.0,
        od=480.0, od_tip=340.0, idf=0.6, ecc=0.2, L=10000.0, heading=12.0, base=(110.0, 500.0),
        prof=('power', (0.08, 2.0)), bend=[230 * ease(f / 25) for f in range(28)],
        holder=dict(kind='pipette', Rg=1.45, slope=0.02),
        fmt=dict(kind='png8'),
        desc='brightfield, pipette from the left at 12 deg; the tube tapers from 24 px (0.48 mm) at the '
             'base to 17 px (0.34 mm) at the tip and is stiffer toward the base: curvature ~ 0.08 + (s/L)^2; '
             '0 -> 230 deg; 800x600; 8-bit PNG folder',
        tests='curvature growing toward the tip (quadratic), outer width tapering along the tube')
    # 3
    add(name='sag_load_tif16', W=768, H=576, um=18.0, n=26, fps=8.0,
        od=300.0, idf=0.6, ecc=0.2, L=8500.0, heading=0.0, base=(110.0, 370.0),
        prof=('uniform', ()), bend=[215 * ease((f - 2) / 21) for f in range(26)],
        sag=-16.0,
        holder=dict(kind='capillary', Rg=2.4, slope=0.0),
        cam=dict(bits=16, fw=20000.0, read=8.0),
        fmt=dict(kind='tif16'),
        desc='brightfield, thick glass capillary from the left; an in-plane distributed load (gravity, with the '
             'microscope on its side) makes the free tube sag (curvature ~ (L-s)^2 when straight); uniform '
             'pneumatic curvature is added (0 -> 215 deg) and the load moment is re-solved for every shape '
             '(beam equation, so the load changes its effect as the tube curls: -15.6 deg at rest, +218.5 deg '
             'at the end, where the load now helps); '
             '768x576; 16-bit multi-page TIFF',
        tests='sagging shape: curvature largest at the base at rest, changing along the tube and with '
              'the shape; starts bent the other way (negative)')
    # 4
    add(name='tip_straight_bump_mjpg', W=800, H=600, um=20.0, n=30, fps=10.0,
        od=400.0, idf=0.6, ecc=0.2, L=10000.0, heading=180.0, base=(700.0, 400.0),
        prof=('bump', (0.12, 0.70)), bend=[-170 * ease(f / 27) for f in range(30)],
        holder=dict(kind='clamp', hw=2.3),
        fmt=dict(kind='mjpg', q=80),
        desc='brightfield, opaque clamp on the right; only the middle of the tube bends: curvature ~ '
             'sin^2 between 12 % and 70 % of the length, so the base stretch and the last 30 % (3 mm, '
             '150 px) stay straight; clockwise to -170 deg; 20 px wide; 800x600; MJPG AVI q80',
        tests='straight stretch at the tip and at the base, curvature zero at both ends')
    # 5
    add(name='eight_frames_0_300', W=640, H=480, um=21.875, n=8, fps=2.0,
        od=350.0, idf=0.6, ecc=0.25, L=9000.0, heading=-8.0, base=(150.0, 360.0),
        prof=('ramp', (0.6, 1.4)), bend=list(np.linspace(0, 300, 8)),
        holder=dict(kind='pipette', Rg=1.5, slope=0.015),
        fmt=dict(kind='mjpg', q=85),
        desc='only 8 frames: 0 -> 300 deg in equal steps of 42.9 deg per frame; pipette from the left at '
             '-8 deg; curvature ramp 0.6 -> 1.4; 640x480; MJPG AVI',
        tests='very few frames, large frame-to-frame jumps (no temporal smoothness to lean on)')
    # 6
    steps = [0] * 4 + [90] * 5 + [180] * 5 + [90] * 4 + [0] * 4 + [90] * 3 + [180] * 3
    creep = []
    for f, b in enumerate(steps):
        k = 0
        while f - k - 1 >= 0 and steps[f - k - 1] == b:
            k += 1
        creep.append(b + (0.9 * k if b else 0.0))
    add(name='step90_deflate_bottom', W=640, H=480, um=25.0, n=len(creep), fps=5.0,
        od=375.0, idf=0.6, ecc=0.2, L=9000.0, heading=90.0, base=(430.0, 440.0),
        prof=('ramp', (0.7, 1.3)), bend=creep,
        holder=dict(kind='capillary', Rg=1.9, slope=0.0),
        fmt=dict(kind='ffv1'),
        desc='pressure steps: 0 -> 90 -> 180 -> 90 -> 0 -> 90 -> 180 deg, each step a 90 deg jump in one '
             'frame, held 3-5 frames with slow creep (+0.9 deg/frame); two deflation steps; glass '
             'capillary from the bottom border (tube points up); 640x480; FFV1 AVI',
        tests='90 deg jumps in one frame, up and down (deflation); base at the bottom')
    # 7
    add(name='border_top_dye_JPG', W=1024, H=768, um=15.0, n=24, fps=10.0,
        od=300.0, idf=0.62, ecc=0.2, L=10000.0, heading=-90.0, base=('top', 330.0),
        prof=('power', (0.15, 1.5)), bend=[220 * ease(f / 22) for f in range(24)],
        holder=None,
        look=dict(dn_i=-0.06, absorb_l=1.1, absorb=0.06, NA=0.18, lens=0.05),
        fmt=dict(kind='jpg', q=88),
        desc='no holder: the tube enters across the top border pointing down and curls CCW (to the '
             'right, then up) to 220 deg; its lumen is filled with a dark dye solution (the inside is '
             'darker than the walls, weak lumen rims); stiff base (curvature ~ 0.15 + (s/L)^1.5); 20 px '
             'wide, 667 px long; 1024x768; JPEG folder IMG_0001.JPG ... (upper-case extension)',
        tests='base on the top border; dark-filled lumen; .JPG extension; stiff-base profile')
    # 8
    add(name='corner_pipette_mp4_lowbitrate', W=800, H=600, um=20.0, n=30, fps=10.0,
        od=400.0, idf=0.6, ecc=0.2, L=9000.0, heading=135.0, base=(610.0, 430.0),
        prof=('ramp', (0.4, 1.6)), bend=[-240 * ease(f / 27) for f in range(30)],
        holder=dict(kind='pipette', Rg=1.5, slope=0.03),
        fmt=dict(kind='mp4', bitrate=60000),
        desc='tapered glass pipette from the bottom-right corner (tube heading 135 deg, up-left), '
             'curling clockwise to -240 deg; curvature ramp 0.4 -> 1.6; 800x600; MP4 (mp4v) at 60 kbit/s: '
             'strong compression (blocking, smeared edges, keyframe pumping)',
        tests='holder from a corner; strong lossy video compression')
    # 9
    b9 = [200 * ease(f / 15) for f in range(16)] + [200 - 80 * ease(f / 9) for f in range(1, 13)]
    add(name='mirrored_phase_gif', W=640, H=480, um=21.875, n=len(b9), fps=10.0,
        od=350.0, idf=0.6, ecc=0.2, L=9000.0, heading=0.0, base=(140.0, 330.0),
        prof=('ramp', (0.3, 1.7)), bend=b9, flip='h',
        holder=dict(kind='pipette', Rg=1.5, slope=0.015),
        look=dict(kind='phase', dn_i=-0.05, ph_depth=0.8, halo=7.0, absorb=0.05),
        fmt=dict(kind='gif'),
        desc='phase contrast (dark tube, bright halo; water-filled lumen) with the image mirrored left-right '
             '(camera flip): pipette on the right, bending clockwise to -200 deg, then deflating back to '
             '-120 deg; 640x480; animated GIF (grey palette)',
        tests='phase halo look; mirrored image; deflation within the video; GIF input')
    # 10
    add(name='overexposed_clipped_lzw', W=640, H=480, um=20.0, n=26, fps=10.0,
        od=400.0, idf=0.6, ecc=0.2, L=8500.0, heading=5.0, base=(100.0, 400.0),
        prof=('power', (0.2, 1.0)), bend=[200 * ease(f / 23) for f in range(26)],
        holder=dict(kind='pipette', Rg=1.5, slope=0.015),
        look=dict(absorb=0.06, lens=0.12),
        cam=dict(exposure=1.45),
        fmt=dict(kind='tif8lzw'),
        desc='overexposed brightfield: the background is clipped at 255 everywhere and the thin-wall '
             'centre band of the tube is clipped too; only the refraction rims and lumen edges carry '
             'contrast; pipette from the left at 5 deg; 0 -> 200 deg; 640x480; 8-bit multi-page TIFF, LZW',
        tests='saturated background and tube pixels (flat 255 areas); LZW-compressed TIFF')
    # 11
    add(name='lowcontrast_highsnr_y800', W=640, H=480, um=21.875, n=24, fps=10.0,
        od=350.0, idf=0.6, ecc=0.2, L=9000.0, heading=0.0, base=(120.0, 360.0),
        prof=('ramp', (0.5, 1.5)), bend=[180 * ease(f / 21) for f in range(24)],
        holder=dict(kind='capillary', Rg=1.8, slope=0.0),
        look=dict(dn_o=0.010, dn_o_in=0.005, dn_i=-0.012, absorb=0.025, NA=0.06, lens=0.0, rim_max=0.06,
                  dn_g=0.03, dn_gb=0.01, face_s=0.15),
        cam=dict(fw=100000.0, read=3.0, exposure=0.8),
        fmt=dict(kind='y800'),
        desc='index-matched tube (liquid-filled, medium of nearly the same index): only slightly darker than '
             'the background (3-6 %), faint rims, but a high-SNR camera (noise ~0.7 grey level); glass capillary '
             'from the left; 0 -> 180 deg; 640x480; uncompressed 8-bit grey AVI (Y800)',
        tests='low contrast with little noise; uncompressed grey AVI')
    # 12
    add(name='png16_readnoise_lowlight', W=640, H=480, um=21.875, n=24, fps=10.0,
        od=350.0, idf=0.6, ecc=0.2, L=9000.0, heading=-40.0, base=(300.0, 90.0),
        prof=('ramp', (1.3, 0.7)), bend=[-170 * ease(f / 21) for f in range(24)],
        holder=dict(kind='pipette', Rg=1.5, slope=0.015),
        cam=dict(bits=16, fw=1000.0, read=45.0, exposure=0.75, offset=0.03),
        fmt=dict(kind='png16'),
        desc='low light: 750 e- background, 45 e- read noise (read noise dominates in the dark rims), '
             '16-bit PNG sequence spanning the full 16-bit range with an offset; pipette from the upper '
             'left (heading -40 deg); curvature decreasing toward the tip (1.3 -> 0.7); 0 -> -170 deg',
        tests='16-bit PNG; very noisy frames (read noise)')
    # 13
    add(name='gamma_overcurl_cw440', W=800, H=600, um=18.0, n=30, fps=10.0,
        od=300.0, idf=0.6, ecc=0.2, L=8500.0, heading=0.0, base=(280.0, 130.0),
        prof=('ramp', (1.1, 0.9)), bend=[-440 * ease(f / 27) for f in range(30)],
        holder=dict(kind='capillary', Rg=2.2, slope=0.0),
        cam=dict(gamma=2.2, exposure=0.8),
        fmt=dict(kind='ffv1'),
        desc='gamma-encoded brightfield (camera gamma 1/2.2: dark rims compressed, background lifted); '
             'thick glass capillary from the left; curvature decreasing slightly toward the tip (1.1 -> 0.9), '
             'so the second turn lies just outside the first: from about -330 deg the tip region runs over '
             'the capillary and then over the tube\'s own base region; -440 deg at the end; 17 px wide, '
             '472 px long; 800x600; FFV1 AVI',
        tests='clockwise over-curl past a full turn, crossing its own base region and the holder; '
              'gamma-encoded intensities')
    # 14
    add(name='darkfield_overcurl_ccw420', W=800, H=600, um=18.0, n=30, fps=10.0,
        od=320.0, idf=0.6, ecc=0.2, L=8500.0, heading=180.0, base=(510.0, 130.0),
        prof=('ramp', (1.15, 0.85)), bend=[420 * ease(f / 27) for f in range(30)],
        holder=dict(kind='pipette', Rg=1.5, slope=0.015),
        look=dict(kind='df', NA=0.45, bg=0.035, kdf=0.8, df_lumen=0.6),
        fmt=dict(kind='png8'),
        desc='dark-field: black background, the tube shows as bright outer edges and bright lumen edges '
             '(the glass pipette likewise); pipette from the right; curvature 1.15 -> 0.85 along the '
             'tube; counter-clockwise over-curl to 420 deg whose tip region crosses the pipette and then '
             'the tube\'s base region; 18 px wide, 472 px long; 800x600; 8-bit PNG folder',
        tests='over-curl past a full turn in a dark-field look; crossings where only edges are visible')
    # 15
    add(name='second_tube_lying', W=800, H=600, um=20.0, n=26, fps=10.0,
        od=350.0, idf=0.6, ecc=0.2, L=9000.0, heading=0.0, base=(100.0, 400.0),
        prof=('ramp', (0.4, 1.6)), bend=[200 * ease(f / 23) for f in range(26)],
        holder=dict(kind='pipette', Rg=1.5, slope=0.015),
        clutter=dict(lying=dict(x=460.0, y=560.0, heading=14.0, length=300.0)),
        fmt=dict(kind='mjpg', q=85),
        desc='a second, stationary, straight piece of the same tubing (6 mm, open cut ends, same width and '
             'look) lies in the dish in the lower right, never touching the actuator; actuator from a '
             'pipette on the left, 0 -> 200 deg; 800x600; MJPG AVI',
        tests='a tube-like distractor of identical appearance in the field')
    # 16
    add(name='scratch_across_field', W=640, H=480, um=21.875, n=26, fps=10.0,
        od=350.0, idf=0.6, ecc=0.2, L=9000.0, heading=0.0, base=(110.0, 170.0),
        prof=('ramp', (0.3, 1.7)), bend=[-190 * ease(f / 23) for f in range(26)],
        holder=dict(kind='pipette', Rg=1.5, slope=0.015),
        clutter=dict(scratches=[dict(x=0.0, y=330.0, angle=22.0, w=0.9, depth=0.45, flank=0.12),
                                dict(x=0.0, y=60.0, angle=-8.0, w=0.6, depth=0.18, flank=0.05)]),
        fmt=dict(kind='mjpg', q=85),
        desc='two straight scratches in the dish bottom run across the whole field (a dark 2 px line with '
             'bright flanks at 22 deg, a fainter one at -8 deg); the tube (pipette from the left) curls '
             'clockwise down to -190 deg across the strong one; 640x480; MJPG AVI',
        tests='long straight dark line crossing the field and the tube')
    # 17
    add(name='long_angled_holder', W=1280, H=960, um=16.0, n=24, fps=10.0,
        od=350.0, idf=0.6, ecc=0.2, L=11000.0, heading=-32.0, base=(440.0, 315.0),
        prof=('power', (0.1, 1.2)), bend=[190 * ease(f / 21) for f in range(24)],
        holder=dict(kind='pipette', Rg=1.5, slope=0.04),
        fmt=dict(kind='mjpg', q=80),
        desc='a long tapered glass pipette enters from the left border high up at -32 deg and runs 520 px '
             '(40 % of the frame width) to the base; an 11 mm (690 px) tube, stiff base, curling CCW to '
             '190 deg; 22 px wide; 1280x960; MJPG AVI',
        tests='long oblique holder crossing a large part of the frame; base far from the border')
    # 18
    add(name='tiny_5px_1600x1200', W=1600, H=1200, um=50.0, n=24, fps=10.0,
        od=240.0, idf=0.6, ecc=0.15, L=10000.0, heading=0.0, base=(700.0, 640.0),
        prof=('ramp', (0.4, 1.6)), bend=[240 * ease(f / 21) for f in range(24)],
        holder=dict(kind='pipette', Rg=1.6, slope=0.01),
        look=dict(NA=0.2), psf=0.8,
        clutter=dict(dust=40),
        fmt=dict(kind='png8'),
        desc='low magnification: a 4.8 px wide, 200 px long tube in a 1600x1200 frame (50 um/px) with '
             'out-of-focus dust; thin pipette from the left reaching the middle; 0 -> 240 deg; 8-bit PNG',
        tests='tiny tube in a large, mostly empty frame')
    # 19
    add(name='huge_40px_curl_640', W=640, H=480, um=12.5, n=26, fps=10.0,
        od=500.0, idf=0.6, ecc=0.2, L=8000.0, heading=-8.0, base=(50.0, 440.0),
        prof=('ramp', (0.3, 1.7)), bend=[100 + 230 * ease(f / 23) for f in range(26)], rest=(('uniform', ()), 100.0),
        holder=dict(kind='capillary', Rg=1.35, slope=0.0),
        psf=1.3,
        fmt=dict(kind='png8'),
        desc='high magnification: 40 px wide, 640 px long tube (8 mm at 12.5 um/px) in a 640x480 frame, '
             'pre-curved at rest (100 deg, uniform), glass capillary from the left border low down (heading '
             '-8 deg); curls CCW to 330 deg (pressure part: ramp 0.3 -> 1.7), nearly filling the frame; '
             '8-bit PNG folder',
        tests='wide tube, length equal to the frame width, curling; thick walls visible')
    # 20
    b20 = [190 * ease(f / 15) for f in range(16)] + [190 - 150 * ease(f / 9) for f in range(1, 11)] + [40.0] * 4
    add(name='fluor_stiffbase_deflate_tif16', W=640, H=480, um=20.0, n=len(b20), fps=10.0,
        od=380.0, idf=0.6, ecc=0.2, L=9000.0, heading=0.0, base=(110.0, 330.0),
        prof=('power', (0.1, 1.5)), bend=b20,
        holder=dict(kind='pipette', Rg=1.5, slope=0.015),
        look=dict(kind='fluor', kf=0.55, bg=0.04, haze=0.25, glass_glow=0.02),
        cam=dict(bits=16, fw=4000.0, read=5.0, exposure=1.0, scale12=True),
        fmt=dict(kind='tif16'),
        desc='fluorescence (dyed PDMS wall bright, lumen dark), faintly glowing pipette from the left; '
             'stiff base (0.1 + (s/L)^1.5); inflates to 190 deg then deflates to 40 deg and holds; '
             '12-bit camera in a 16-bit TIFF stack',
        tests='bright look with a non-arc profile; deflation within the video')
    # 21
    add(name='vflip_portrait_clamp', W=480, H=640, um=24.0, n=26, fps=10.0,
        od=360.0, idf=0.6, ecc=0.2, L=9500.0, heading=90.0, base=(80.0, 480.0),
        prof=('rpower', (0.15, 1.0)), bend=[-170 * ease(f / 23) for f in range(26)], flip='v',
        holder=dict(kind='clamp', hw=2.4),
        fmt=dict(kind='ffv1'),
        desc='portrait 480x640 with the image flipped upside down: an opaque clamp (160 px) at the top, '
             'the tube hangs down and bends counter-clockwise (toward the right) to +170 deg; the tip is '
             'stiffer (curvature ~ 0.15 + (1-s/L)); 15 px wide; FFV1 AVI',
        tests='flipped image, base at the top, portrait frame; curvature decreasing toward the tip')
    # 22
    add(name='basecurl_decay_mjpg', W=800, H=600, um=20.0, n=26, fps=10.0,
        od=400.0, idf=0.6, ecc=0.2, L=9000.0, heading=25.0, base=(330.0, 560.0),
        prof=('rpower', (0.0, 2.0)), bend=[160 * ease(f / 23) for f in range(26)],
        holder=dict(kind='pipette', Rg=1.5, slope=0.02),
        fmt=dict(kind='mjpg', q=85),
        desc='only the base region bends: curvature ~ (1-s/L)^2, the distal third is nearly straight; '
             'pipette from the lower left at 25 deg; 0 -> 160 deg; 800x600; MJPG AVI',
        tests='curvature concentrated near the base (tip tangent set by the base region)')
    # 23
    add(name='corner_border_entry', W=640, H=480, um=25.0, n=26, fps=10.0,
        od=350.0, idf=0.6, ecc=0.2, L=9000.0, heading=55.0, base=('left', 458.0),
        prof=('ramp', (0.5, 1.5)), bend=[-140 * ease(f / 23) for f in range(26)],
        holder=None,
        fmt=dict(kind='ffv1'),
        desc='no holder: the tube enters across the left border 22 px above the bottom-left corner, heading '
             '55 deg (up-right), and curls clockwise (over to the right and down) to -140 deg; base on the '
             'border at col -0.5; 14 px wide; 640x480; FFV1 AVI',
        tests='base at the border next to a corner, oblique entry; clockwise')
    return S


def settings(sc):
    """Fill defaults."""
    s = dict(sc)
    look = dict(LOOK_BF)
    look.update(sc.get('look', {}))
    s['look'] = look
    cam = dict(CAM)
    cam.update(sc.get('cam', {}))
    s['cam'] = cam
    s.setdefault('psf', 1.0)
    s.setdefault('flip', None)
    s.setdefault('clutter', {})
    s.setdefault('od_tip', s['od'])
    s.setdefault('sag', None)
    s.setdefault('rest', None)
    s.setdefault('vignette', 0.10)
    s.setdefault('grad', (0.04, -0.03))
    return s


def seed_of(name, extra=0):
    return int(hashlib.sha256(name.encode()).hexdigest()[:12], 16) + 1000003 * extra


# ----------------------------------------------------------------------------- geometry per frame

def base_point(s):
    b = s['base']
    th = math.radians(s['heading'])
    if b[0] == 'top':
        return float(b[1]), 0.5, th          # row -0.5 -> Y = +0.5
    if b[0] == 'bottom':
        return float(b[1]), -(s['H'] - 0.5), th
    if b[0] == 'left':
        return -0.5, -float(b[1]), th
    if b[0] == 'right':
        return s['W'] - 0.5, -float(b[1]), th
    return float(b[0]), -float(b[1]), th


def holder_length(s, bx, by, th):
    """Arc length behind the base until the axis leaves the canvas (plus slack)."""
    W, H = s['W'], s['H']
    lo = np.linspace(0, 4 * (W + H), 20001)
    x = bx - lo * math.cos(th)
    y = -(by - lo * math.sin(th))
    inside = (x > -MARGIN - 40) & (x < W + MARGIN + 40) & (y > -MARGIN - 40) & (y < H + MARGIN + 40)
    k = np.nonzero(~inside)[0]
    return float(lo[k[0]]) + 5.0


def sag_heading(th0, K, f, F, L, g, n=1600):
    """Heading of a cantilever under pneumatic curvature K f(s/L)/L and a distributed load in -Y
    (beam equation theta' = kappa_p + M/EI, M(s) = -g int_s^L (x(t)-x(s)) dt), solved by fixed point."""
    s = np.linspace(0, L, n + 1)
    ds = L / n
    kp = K * f(s / L) / L
    th = th0 + K * F(s / L)

    def cum(a):
        return np.concatenate([[0.0], np.cumsum((a[1:] + a[:-1]) * ds / 2)])
    for _ in range(400):
        x = cum(np.cos(th))
        Xc = cum(x)
        M = -g * ((Xc[-1] - Xc) - x * (L - s))
        new = th0 + cum(kp + M)
        if np.abs(new - th).max() < 1e-13:
            th = new
            break
        th = 0.5 * th + 0.5 * new
    sp = CubicSpline(s, th)
    dsp = sp.derivative()
    return lambda q: (sp(q), dsp(q))


def frame_geometry(s, f):
    """Curve (px, math frame, before any flip) of frame f, plus its truth bend in degrees."""
    Lpx = s['L'] / s['um']
    bx, by, th0 = base_point(s)
    fK, FK = prof_fns(*s['prof'])
    bend = float(s['bend'][f])
    if s['sag'] is not None:
        g = -math.radians(s['sag']) * 6 / Lpx ** 3      # straight horizontal cantilever: tip = -g L^3/6
        hfun = sag_heading(th0, math.radians(bend), fK, FK, Lpx, g)
    else:
        K = math.radians(bend)
        if s['rest']:
            fr, Fr = prof_fns(*s['rest'][0])
            Kr = math.radians(s['rest'][1])
            K = K - Kr
        else:
            fr = Fr = None
            Kr = 0.0

        def hfun(q, K=K, Kr=Kr):
            t = q / Lpx
            th = th0 + K * FK(t)
            ka = K * fK(t) / Lpx
            if Fr is not None:
                th = th + Kr * Fr(t)
                ka = ka + Kr * fr(t) / Lpx
            return th, ka
    ext = holder_length(s, bx, by, th0)
    c = Curve(hfun, Lpx, bx, by, ext)
    c.ext = ext
    return c, math.degrees(c.thL - c.th0)


def lumen_sign(s):
    b = np.asarray(s['bend'], float)
    m = b[np.argmax(np.abs(b))] if len(b) else 1.0
    return -1.0 if m >= 0 else 1.0      # lumen toward the convex side (thin wall outside the bend)


def make_objects(s, c, twin=False):
    um = s['um']
    look = s['look']
    ro0, ro1 = s['od'] / 2 / um, s['od_tip'] / 2 / um
    idf = s['idf']
    ecc = 0.0 if twin else s['ecc']
    e = lumen_sign(s) * ecc * (ro0 - idf * ro0)
    wall0 = 2 * ro0 * (1 - idf)
    opt = dict(look)
    opt['mu_w'] = look['absorb'] / wall0
    opt['mu_l'] = look['absorb_l'] / (2 * idf * ro0)
    tubes = [Tube(c, ro0, ro1, idf, e, opt)]
    if not twin and 'lying' in s['clutter']:
        ly = s['clutter']['lying']
        lc = straight_curve(ly['x'], -ly['y'], math.radians(ly['heading']), ly['length'])
        tubes.append(Tube(lc, ro0, ro0, idf, 0.0, opt, cap=False, s_lo=0.0, actuator=False))
    holder = None
    h = s['holder']
    if h:
        gopt = dict(look)
        Rg0 = h.get('Rg', 1.5) * ro0
        gopt['mu_g'] = look['absorb_g'] / max(2 * (Rg0 - ro0 * 1.04), 1.0)
        holder = Holder(h['kind'], c.Xn[0], c.Yn[0], c.th0,
                        c.ext, Rg0, h.get('slope', 0.0), ro0 * 1.04, 0.0, h.get('hw', 2.3) * ro0, gopt)
    return tubes, holder


# ----------------------------------------------------------------------------- images

def field_maps(s, rng_static):
    """Static multiplicative maps on the canvas: illumination, dust, scratches."""
    W, H = s['W'], s['H']
    cw, chh = W + 2 * MARGIN, H + 2 * MARGIN
    rr, cc = np.mgrid[0:chh, 0:cw].astype(float)
    rr -= MARGIN
    cc -= MARGIN
    xn = (cc - (W - 1) / 2) / (max(W, H) / 2)
    yn = (rr - (H - 1) / 2) / (max(W, H) / 2)
    illum = (1 - s['vignette'] * (xn ** 2 + yn ** 2)) * (1 + s['grad'][0] * xn + s['grad'][1] * yn)
    mult = np.ones((chh, cw))
    cl = s['clutter']
    nd = cl.get('dust', 6)
    for _ in range(nd):
        x, y = rng_static.uniform(0, W), rng_static.uniform(0, H)
        sg = rng_static.uniform(1.5, 7.0)
        a = rng_static.uniform(0.02, 0.10)
        r = int(4 * sg) + 2
        r0, r1 = int(y) - r + MARGIN, int(y) + r + MARGIN
        c0, c1 = int(x) - r + MARGIN, int(x) + r + MARGIN
        r0, c0 = max(r0, 0), max(c0, 0)
        sub = (slice(r0, min(r1, chh)), slice(c0, min(c1, cw)))
        mult[sub] *= 1 - a * np.exp(-((rr[sub] - y) ** 2 + (cc[sub] - x) ** 2) / (2 * sg * sg))
    for sc in cl.get('scratches', []):
        a = math.radians(sc['angle'])
        # line through (x, y) in (col,row) with direction (cos a, -sin a): normal (sin a, cos a)
        dist = (cc - sc['x']) * math.sin(a) + (rr - sc['y']) * math.cos(a)
        w = sc['w']
        mult *= (1 - sc['depth'] * np.exp(-0.5 * (dist / w) ** 2)
                 + sc['flank'] * np.exp(-0.5 * ((np.abs(dist) - 2.2 * w) / w) ** 2))
    return illum, mult


def render_linear(s, f, twin=False, look_override=None, clean=False, local=False):
    """Linear intensity image (H,W) in units of full scale, before the camera; and truth geometry.
    twin: concentric lumen, no clutter objects; clean: no illumination field, dust or scratches;
    local: without the non-local optics (phase halo, fluorescence haze)."""
    c, bend = frame_geometry(s, f)
    tubes, holder = make_objects(s, c, twin=twin)
    look = dict(s['look'])
    if look_override:
        look.update(look_override)
    kind = look['kind']
    W, H = s['W'], s['H']
    cw, chh = W + 2 * MARGIN, H + 2 * MARGIN
    if kind == 'phase':
        ro0 = s['od'] / 2 / s['um']
        look['kph'] = look['ph_depth'] / (look['dn_o'] * 2 * ro0)
    means, rc = render_channels(tubes, holder, W, H, look)
    if kind == 'mask':
        out = {}
        for k in ('M', 'H'):
            img = np.zeros((chh, cw))
            if rc is not None:
                img[rc] = means[k]
            out[k] = img[MARGIN:MARGIN + H, MARGIN:MARGIN + W]
        return out, c, bend
    if clean:
        illum = np.ones((chh, cw))
        mult = np.ones((chh, cw))
    else:
        illum, mult = field_maps(s, np.random.default_rng(seed_of(s['name'], 7)))
    bg = look.get('bg', 1.0)
    if kind == 'bf':
        T = np.ones((chh, cw))
        if rc is not None:
            T[rc] = means['T']
        img = T * mult
        img = ndimage.gaussian_filter(img, s['psf']) * illum
    elif kind == 'phase':
        T = np.ones((chh, cw))
        O = np.zeros((chh, cw))
        if rc is not None:
            T[rc] = means['T']
            O[rc] = means['OPL']
        ph = O if local else O - ndimage.gaussian_filter(O, look['halo'])
        img = np.clip(T * (1 - look['kph'] * ph), 0.02, None) * mult
        img = ndimage.gaussian_filter(img, s['psf']) * illum
    elif kind == 'df':
        D = np.zeros((chh, cw))
        if rc is not None:
            D[rc] = means['DF']
        sig = D * look['kdf']
        img = ndimage.gaussian_filter(sig, s['psf']) * illum + bg * (2 - mult if not clean else 1.0)
    elif kind == 'fluor':
        E = np.zeros((chh, cw))
        if rc is not None:
            E[rc] = means['EM']
        ro0 = s['od'] / 2 / s['um']
        E = E / (2 * ro0 * (1 - s['idf']))
        if not local:
            E = E + look['haze'] * ndimage.gaussian_filter(E, 3 * ro0)
        img = ndimage.gaussian_filter(E, s['psf']) * illum + bg * illum
    else:
        raise ValueError(kind)
    return img[MARGIN:MARGIN + H, MARGIN:MARGIN + W], c, bend


def camera(s, img, f):
    cam = s['cam']
    rng = np.random.default_rng(seed_of(s['name'], 100 + f))
    e = np.clip(img * cam['exposure'], 0, None) * cam['fw']
    e = rng.poisson(e).astype(float) + rng.normal(0.0, cam['read'], e.shape)
    v = e / cam['fw'] + cam['offset']
    if cam['gamma']:
        v = np.clip(v, 0, 1) ** (1.0 / cam['gamma'])
    if cam['bits'] == 8:
        return np.clip(np.round(v * 255), 0, 255).astype(np.uint8)
    top = 4095 if cam.get('scale12') else 65535
    return np.clip(np.round(v * top), 0, top).astype(np.uint16)


def apply_flip(s, a):
    if s['flip'] in ('h', 'hv'):
        a = a[:, ::-1]
    if s['flip'] in ('v', 'hv'):
        a = a[::-1, :]
    return np.ascontiguousarray(a)


def flip_xy(s, X, Y):
    """Math-frame px coordinates -> after the flip."""
    X, Y = np.asarray(X, float), np.asarray(Y, float)
    if s['flip'] in ('h', 'hv'):
        X = (s['W'] - 1) - X
    if s['flip'] in ('v', 'hv'):
        Y = -(s['H'] - 1) - Y
    return X, Y


def bend_sign(s):
    return -1.0 if s['flip'] in ('h', 'v') else 1.0


def truth_frame(s, c, bend):
    L = c.L
    n = int(math.ceil(L / TRUTH_DS))
    sq = np.concatenate([[0.0, END_EPS], np.linspace(0, L, n + 1)[1:-1], [L - END_EPS, L]])
    X, Y = c.pos(sq)
    X[0], Y[0] = c.Xn[0], c.Yn[0]
    X, Y = flip_xy(s, X, Y)
    return sq, X, Y, bend * bend_sign(s)


# ----------------------------------------------------------------------------- writers

class Writer:
    def __init__(self, s, d):
        self.s, self.d = s, d
        fmt = s['fmt']
        self.kind = fmt['kind']
        W, H = s['W'], s['H']
        self.frames = []
        if self.kind in ('ffv1', 'y800'):
            self.input = 'video.avi'
            fcc = 'FFV1' if self.kind == 'ffv1' else 'Y800'
            self.vw = cv2.VideoWriter(os.path.join(d, self.input), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*fcc),
                                      s['fps'], (W, H), [cv2.VIDEOWRITER_PROP_IS_COLOR, 0])
        elif self.kind == 'mjpg':
            self.input = 'video.avi'
            self.vw = cv2.VideoWriter(os.path.join(d, self.input), cv2.CAP_OPENCV_MJPEG,
                                      cv2.VideoWriter_fourcc(*'MJPG'), s['fps'], (W, H),
                                      [cv2.VIDEOWRITER_PROP_QUALITY, fmt['q']])
        elif self.kind == 'mp4':
            self.input = 'video.mp4'
            self.vw = cv2.VideoWriter(os.path.join(d, self.input), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*'mp4v'),
                                      s['fps'], (W, H), [cv2.VIDEOWRITER_PROP_IS_COLOR, 0,
                                                         cv2.VIDEOWRITER_PROP_BITRATE, fmt['bitrate']])
        elif self.kind in ('png8', 'png16', 'jpg'):
            self.input = 'frames'
            os.makedirs(os.path.join(d, 'frames'), exist_ok=True)
        elif self.kind == 'gif':
            self.input = 'video.gif'
        elif self.kind in ('tif8lzw', 'tif16'):
            self.input = 'stack.tif'
        else:
            raise ValueError(self.kind)
        if hasattr(self, 'vw') and not self.vw.isOpened():
            raise RuntimeError('cannot open video writer for %s' % self.kind)
        self.n = 0

    def add(self, a):
        k = self.kind
        if k in ('ffv1', 'y800', 'mp4'):
            self.vw.write(a)
        elif k == 'mjpg':
            self.vw.write(cv2.cvtColor(a, cv2.COLOR_GRAY2BGR))
        elif k in ('png8', 'png16'):
            cv2.imwrite(os.path.join(self.d, 'frames', 'frame_%04d.png' % self.n), a)
        elif k == 'jpg':
            cv2.imwrite(os.path.join(self.d, 'frames', 'IMG_%04d.JPG' % (self.n + 1)), a,
                        [cv2.IMWRITE_JPEG_QUALITY, self.s['fmt']['q']])
        else:
            self.frames.append(a)
        self.n += 1

    def close(self):
        k = self.kind
        if hasattr(self, 'vw'):
            self.vw.release()
        elif k == 'gif':
            ims = [Image.fromarray(a, 'L') for a in self.frames]
            ims[0].save(os.path.join(self.d, self.input), save_all=True, append_images=ims[1:],
                        duration=int(round(1000 / self.s['fps'])), loop=0, optimize=False)
        elif k == 'tif8lzw':
            tifffile.imwrite(os.path.join(self.d, self.input), np.stack(self.frames), compression='lzw',
                             photometric='minisblack')
        elif k == 'tif16':
            tifffile.imwrite(os.path.join(self.d, self.input), np.stack(self.frames), photometric='minisblack')


def read_frames(s, d):
    """Read the frames back from disk (grey, original dtype)."""
    inp = os.path.join(d, s['input'] if 'input' in s else json.load(open(os.path.join(d, 'scene.json')))['input'])
    k = s['fmt']['kind']
    out = []
    if k in ('ffv1', 'y800', 'mjpg', 'mp4'):
        cap = cv2.VideoCapture(inp)
        while True:
            ok, im = cap.read()
            if not ok:
                break
            out.append(im[..., 1] if im.ndim == 3 else im)
    elif k in ('png8', 'png16', 'jpg'):
        names = sorted(os.listdir(inp))
        for nm in names:
            out.append(cv2.imread(os.path.join(inp, nm), cv2.IMREAD_UNCHANGED))
    elif k == 'gif':
        g = Image.open(inp)
        for i in range(g.n_frames):
            g.seek(i)
            out.append(np.array(g.convert('L')))
    else:
        a = tifffile.imread(inp)
        out = list(a if a.ndim == 3 else a[None])
    return out


# ----------------------------------------------------------------------------- per-scene render

def placement(s, c):
    """Min distance (px) of the body (s in [0,L]) to the frame's outer edge, and crossing flags."""
    W, H = s['W'], s['H']
    m = c.s >= (0 if s['holder'] else 4 * s['od'] / s['um'])
    tube = Tube.__new__(Tube)
    tube.L, tube.ro0, tube.ro1, tube.idf, tube.cap = c.L, s['od'] / 2 / s['um'], s['od_tip'] / 2 / s['um'], \
        s['idf'], True
    ro, _, _ = Tube.geom(tube, c.s[m])
    X, Y = c.X[m], -c.Y[m]
    marg = np.minimum.reduce([X + 0.5 - ro, W - 0.5 - X - ro, Y + 0.5 - ro, H - 0.5 - Y - ro])
    # self-crossing: points far apart in s but close in space
    sel = np.nonzero(c.s >= 0)[0][::5]
    tree = cKDTree(np.stack([c.X[sel], c.Y[sel]], 1))
    pairs = tree.query_pairs(2.2 * max(tube.ro0, tube.ro1))
    cross = any(abs(c.s[sel[i]] - c.s[sel[j]]) > 6 * tube.ro0 for i, j in pairs)
    # holder crossing: body points with u < 0 near the holder axis
    u = (c.X[sel] - c.Xn[0]) * math.cos(c.th0) + (c.Y[sel] - c.Yn[0]) * math.sin(c.th0)
    v = -(c.X[sel] - c.Xn[0]) * math.sin(c.th0) + (c.Y[sel] - c.Yn[0]) * math.cos(c.th0)
    Rh = (s['holder'] or {}).get('Rg', (s['holder'] or {}).get('hw', 1.0)) * tube.ro0 if s['holder'] else 0
    hcross = bool(s['holder']) and bool(np.any((u < -1) & (np.abs(v) < Rh + tube.ro0)))
    kmax = float(np.abs(c.ka[c.s >= 0]).max()) * tube.ro0
    return float(marg.min()), cross, hcross, kmax


def render_scene(sc, verbose=True):
    t0 = time.time()
    s = settings(sc)
    d = os.path.join(SCENES_DIR, s['name'])
    if os.path.exists(d):
        shutil.rmtree(d)
    os.makedirs(d)
    wr = Writer(s, d)
    um = s['um']
    rows_t, rows_c = [], []
    margins, crosses, hcrosses, kmaxes = [], [], [], []
    for f in range(s['n']):
        img, c, bend = render_linear(s, f)
        a = apply_flip(s, camera(s, img, f))
        wr.add(a)
        mg, cr, hc, km = placement(s, c)
        margins.append(mg)
        crosses.append(cr)
        hcrosses.append(hc)
        kmaxes.append(km)
        sq, X, Y, b = truth_frame(s, c, bend)
        b = b + 0.0      # no negative zero
        t = f / s['fps']
        rows_t.append('%d,%.6f,%.7f,%.7f,%.7f,%.7f,%.7f,%.7f,ok' % (
            f, t, b, X[-1] * um, Y[-1] * um, X[0] * um, Y[0] * um, c.L * um))
        rows_c.extend('%d,%.7f,%.7f,%.7f' % (f, si * um, xi * um, yi * um) for si, xi, yi in zip(sq, X, Y))
    wr.close()
    with open(os.path.join(d, 'truth_tracks.csv'), 'w') as fh:
        fh.write('frame,time_s,bend_angle_deg,tip_x_um,tip_y_um,base_x_um,base_y_um,length_um,status\n')
        fh.write('\n'.join(rows_t) + '\n')
    with open(os.path.join(d, 'truth_centrelines.csv'), 'w') as fh:
        fh.write('frame,s_um,x_um,y_um\n')
        fh.write('\n'.join(rows_c) + '\n')
    ro0 = s['od'] / 2 / um
    bx, by, th0 = base_point(s)
    meta = dict(name=s['name'], description=s['desc'], tests=s['tests'], um_per_px=um, input=wr.input,
                n_frames=s['n'], fps=s['fps'], frame_size=[s['W'], s['H']],
                settings={k: v for k, v in s.items() if k not in ('desc', 'tests', 'name')},
                derived=dict(outer_radius_px=ro0, outer_radius_tip_px=s['od_tip'] / 2 / um,
                             lumen_radius_px=s['idf'] * ro0,
                             lumen_offset_px=lumen_sign(s) * s['ecc'] * ro0 * (1 - s['idf']),
                             length_px=s['L'] / um, base_px_before_flip=[bx, -by],
                             min_margin_px=round(min(margins), 2),
                             frames_crossing_itself=[i for i, v in enumerate(crosses) if v],
                             frames_crossing_holder=[i for i, v in enumerate(hcrosses) if v],
                             max_curvature_x_radius=round(max(kmaxes), 3),
                             seed=seed_of(s['name'])),
                conventions=CONVENTIONS)
    with open(os.path.join(d, 'scene.json'), 'w') as fh:
        json.dump(meta, fh, indent=1, default=lambda o: o.tolist() if hasattr(o, 'tolist') else str(o))
    dt = time.time() - t0
    if verbose:
        print('  %-32s %3d frames  %5.1fs  margin %.1f px%s' % (
            s['name'], s['n'], dt, min(margins), '' if min(margins) >= 3 else '  WARNING: tube near border'),
            flush=True)
    return s['name'], dt


def plan(sc):
    s = settings(sc)
    out = []
    for f in range(s['n']):
        c, bend = frame_geometry(s, f)
        out.append((bend,) + placement(s, c))
    m = min(o[1] for o in out)
    print('%-32s bend %7.1f..%7.1f  margin %6.1f  crosses %s  holder %s  max k*ro %.2f' % (
        s['name'], min(o[0] for o in out), max(o[0] for o in out), m,
        [i for i, o in enumerate(out) if o[2]][:3], [i for i, o in enumerate(out) if o[3]][:3],
        max(o[4] for o in out)))


# ----------------------------------------------------------------------------- self-checks

DEBUG_C = False
LOSSLESS = ('png8', 'png16', 'tif8lzw', 'tif16', 'gif', 'ffv1', 'y800')


def load_truth(d):
    import pandas as pd
    tr = pd.read_csv(os.path.join(d, 'truth_tracks.csv'))
    cl = pd.read_csv(os.path.join(d, 'truth_centrelines.csv'))
    return tr, {f: g for f, g in cl.groupby('frame')}


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def ro_settings(s, S):
    """Outer radius at arc length S (px), re-implemented from the settings (cap follows the centreline)."""
    um = s['um']
    r0, r1, L = s['od'] / 2 / um, s['od_tip'] / 2 / um, s['L'] / um
    sc = L - r1
    r = r0 + (r1 - r0) * np.clip(S / sc, 0, 1)
    return np.where(S > sc, np.sqrt(np.clip(r1 ** 2 - (S - sc) ** 2, 0, None)), r)


def seg_foot(P, S, Q, tree):
    """Foot of points Q (m,2) on the polyline P (n,2) (arc length S): (s, signed d (+left), k, t_raw)."""
    _, j = tree.query(Q)
    n = len(P)
    best = np.full(len(Q), np.inf)
    out_s = np.zeros(len(Q))
    out_d = np.zeros(len(Q))
    out_k = np.zeros(len(Q), int)
    out_t = np.zeros(len(Q))
    for k in (np.clip(j - 1, 0, n - 2), np.clip(j, 0, n - 2)):
        A, B = P[k], P[k + 1]
        AB = B - A
        L2 = (AB ** 2).sum(1)
        traw = ((Q - A) * AB).sum(1) / L2
        tc = np.clip(traw, 0, 1)
        F = A + tc[:, None] * AB
        dist = np.hypot(*(Q - F).T)
        better = dist < best
        best = np.where(better, dist, best)
        sgn = np.sign(AB[:, 0] * (Q - F)[:, 1] - AB[:, 1] * (Q - F)[:, 0])
        out_d = np.where(better, sgn * dist, out_d)
        out_s = np.where(better, S[k] + tc * (S[k + 1] - S[k]), out_s)
        out_k = np.where(better, k, out_k)
        out_t = np.where(better, traw, out_t)
    return out_s, out_d, out_k, out_t


def jitter(n, seed, m=8):
    """Stratified m x m samples per pixel, jittered independently in every pixel (no pattern shared
    between pixels, so sampling errors along a long straight edge do not add up)."""
    rng = np.random.default_rng(seed)
    g = np.arange(m) / m - 0.5
    jx, jy = np.meshgrid(g, g)
    base = np.stack([jx.ravel(), jy.ravel()], 1)
    return base[None] + rng.uniform(0, 1.0 / m, (n, m * m, 2))


def raster_truth(s, P, S, cand):
    """Independent coverage of the tube body from the truth points (math px coords): every pixel of
    cand with 64 jittered samples, the pixels found on an edge again with 256."""
    cov = _raster(s, P, S, cand, 8, 12345)
    edge = cand & (cov > 0) & (cov < 1)
    edge = ndimage.binary_dilation(edge) & cand
    cov2 = _raster(s, P, S, edge, 16, 23456)
    cov[edge] = cov2[edge]
    return cov


def _raster(s, P, S, cand, m, seed):
    rr, cc = np.nonzero(cand)
    off = jitter(len(rr), seed, m)
    K = m * m
    Q = np.stack([(cc[:, None] + off[:, :, 0]).ravel(), (-(rr[:, None] + off[:, :, 1])).ravel()], 1)
    inside = np.zeros(len(Q), bool)
    n = len(P)
    ro_max = float(max(s['od'], s['od_tip']) / 2 / s['um'])
    piece = max(8.0, ro_max)
    edges = list(np.arange(0, S[-1], piece)) + [S[-1] + 1]
    for a, b in zip(edges[:-1], edges[1:]):
        sel = np.nonzero((S >= a - ro_max - 3) & (S <= b + ro_max + 3))[0]
        lo, hi = sel[0], sel[-1] + 1
        PP = P[lo:hi]
        box = (PP[:, 0].min() - ro_max - 1, PP[:, 0].max() + ro_max + 1, PP[:, 1].min() - ro_max - 1,
               PP[:, 1].max() + ro_max + 1)
        mm = np.nonzero((Q[:, 0] > box[0]) & (Q[:, 0] < box[1]) & (Q[:, 1] > box[2]) & (Q[:, 1] < box[3]))[0]
        if not len(mm):
            continue
        sf, d, k, traw = seg_foot(PP, S[lo:hi], Q[mm], cKDTree(PP))
        k = k + lo
        ok = (sf >= a) & (sf < b) & ~((k == 0) & (traw < 0)) & ~((k == n - 2) & (traw > 1))
        inside[mm] |= ok & (np.abs(d) < ro_settings(s, sf))
    cov = np.zeros(cand.shape)
    cov[rr, cc] = inside.reshape(-1, K).mean(1)
    return cov


def holder_raster(s, B, th, cand):
    """Independent coverage of the holder from the truth base B and base heading th (math px), 256
    jittered samples per pixel."""
    h = s['holder']
    ro0 = s['od'] / 2 / s['um']
    rr, cc = np.nonzero(cand)
    off = jitter(len(rr), 54321, 16)
    X = (cc[:, None] + off[:, :, 0]).ravel()
    Y = (-(rr[:, None] + off[:, :, 1])).ravel()
    u = (X - B[0]) * math.cos(th) + (Y - B[1]) * math.sin(th)
    v = -(X - B[0]) * math.sin(th) + (Y - B[1]) * math.cos(th)
    if h['kind'] == 'clamp':
        Rr = h.get('hw', 2.3) * ro0
    else:
        Rr = h.get('Rg', 1.5) * ro0 + h.get('slope', 0.0) * np.maximum(-u, 0)
    ins = (u < 0) & (np.abs(v) < Rr)
    cov = np.zeros(cand.shape)
    cov[rr, cc] = ins.reshape(-1, 256).mean(1)
    return cov


def math_pts(g, um):
    return np.stack([g.x_um.values / um, g.y_um.values / um], 1), g.s_um.values / um


def check_conventions(lines):
    ok = True
    # pixel centres: a straight rod (no cap, flat ends) on row 100.0 and on row 100.25
    for row in (100.0, 100.25):
        c = straight_curve(20.0, -row, 0.0, 160.0)
        opt = dict(LOOK_BF, mu_w=0.0, mu_l=0.0)
        tb = Tube(c, 6.0, 6.0, 0.0, 0.0, opt, cap=False, s_lo=0.0)
        means, rc = render_channels([tb], None, 200, 200, dict(kind='mask'))
        img = np.zeros((200 + 2 * MARGIN, 200 + 2 * MARGIN))
        img[rc] = means['M']
        img = img[MARGIN:-MARGIN, MARGIN:-MARGIN]
        cols = img[:, 40:160]
        cen = (cols * np.arange(200)[:, None]).sum(0) / cols.sum(0)
        good = abs(cen.mean() - row) < 0.004 and abs(cols.sum(0).mean() - 12.0) < 0.01
        ok &= good
        lines.append('  rod on row %.2f: coverage centroid per column %.5f (min %.5f max %.5f), width %.4f px  %s'
                     % (row, cen.mean(), cen.min(), cen.max(), cols.sum(0).mean(), 'ok' if good else 'FAIL'))
    # sign: +90 deg uniform bend from a base pointing right ends up and to the right
    fK, FK = prof_fns('uniform')
    K = math.radians(90)
    c = Curve(lambda q: (K * FK(q / 100.0), K * fK(q / 100.0) / 100.0), 100.0, 0.0, 0.0, 0.0)
    x, y = c.pos(np.array([100.0]))
    good = abs(x[0] - 200 / math.pi) < 1e-6 and abs(y[0] - 200 / math.pi) < 1e-6
    ok &= good
    lines.append('  +90 deg over 100 px from (0,0) heading right: tip (%.5f, %.5f) (y up, i.e. row %.3f); '
                 'expected (63.66198, 63.66198)  %s' % (x[0], y[0], -y[0], 'ok' if good else 'FAIL'))
    return ok


def check_scene(s):
    """Returns (ok, lines)."""
    from scipy.integrate import solve_ivp
    name = s['name']
    d = os.path.join(SCENES_DIR, name)
    lines = ['%s' % name]
    ok = True
    if not os.path.exists(os.path.join(d, 'scene.json')):
        return False, lines + ['  not rendered']
    meta = json.load(open(os.path.join(d, 'scene.json')))
    um = meta['um_per_px']
    tr, cl = load_truth(d)
    n = s['n']
    # --- A. truth files
    worst = dict(turn=0.0, length=0.0, spacing=0.0, ends=0.0, integ=0.0)
    for f in range(n):
        g = cl[f]
        P, S = math_pts(g, um)
        row = tr.iloc[f]
        seg = np.diff(P, axis=0)
        phi = np.arctan2(seg[:, 1], seg[:, 0])
        turn = math.degrees(np.sum(wrap(np.diff(phi))))
        worst['turn'] = max(worst['turn'], abs(turn - row.bend_angle_deg))
        plen = np.hypot(*seg.T).sum()
        worst['length'] = max(worst['length'], abs(plen - row.length_um / um), abs(S[-1] - row.length_um / um))
        worst['spacing'] = max(worst['spacing'], np.hypot(*seg.T).max())
        e1 = math.hypot(P[0, 0] - row.base_x_um / um, P[0, 1] - row.base_y_um / um)
        e2 = math.hypot(P[-1, 0] - row.tip_x_um / um, P[-1, 1] - row.tip_y_um / um)
        worst['ends'] = max(worst['ends'], e1, e2)
        if f in (0, n // 2, n - 1):
            c, bend = frame_geometry(s, f)
            sol = solve_ivp(lambda q, y: [math.cos(c.theta(np.array([q]))[0]), math.sin(c.theta(np.array([q]))[0])],
                            (0, c.L), [c.Xn[0], c.Yn[0]], method='DOP853', rtol=1e-12, atol=1e-10,
                            dense_output=True)
            Xi, Yi = sol.sol(S)
            Xi, Yi = flip_xy(s, Xi, Yi)
            worst['integ'] = max(worst['integ'], np.hypot(Xi - P[:, 0], Yi - P[:, 1]).max())
    good = (worst['turn'] < 0.02 and worst['length'] < 0.01 and worst['spacing'] <= 0.35 and worst['ends'] < 1e-3
            and worst['integ'] < 1e-3)
    ok &= good
    lines.append('  A truth: |bend - polyline turning| max %.4f deg; |length - polyline length| max %.5f px; '
                 'spacing max %.3f px; ends %.1e px; independent ODE integration max %.1e px  %s'
                 % (worst['turn'], worst['length'], worst['spacing'], worst['ends'], worst['integ'],
                    'ok' if good else 'FAIL'))
    if s['sag'] is not None:
        # beam equation residual on the truth polyline: kappa = kappa_p + M/EI
        res = 0.0
        Lpx = s['L'] / um
        g_ = -math.radians(s['sag']) * 6 / Lpx ** 3
        fK, _ = prof_fns(*s['prof'])
        for f in (0, n // 2, n - 1):
            P, S = math_pts(cl[f], um)
            P, S = P[1:-1], S[1:-1]
            seg = np.diff(P, axis=0)
            phi = np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))
            sm = (S[1:] + S[:-1]) / 2
            kap = np.diff(phi) / np.diff(sm)
            sk = (sm[1:] + sm[:-1]) / 2
            x = np.interp(sk, S, P[:, 0])
            xs = P[:, 0]
            # M(s) = -g int_s^L (x(t) - x(s)) dt, trapezoid on the truth points
            cum = np.concatenate([[0.0], np.cumsum((xs[1:] + xs[:-1]) / 2 * np.diff(S))])
            Xc = np.interp(sk, S, cum)
            M = -g_ * ((cum[-1] - Xc) - x * (S[-1] - sk))
            kp = math.radians(s['bend'][f]) * fK(sk / Lpx) / Lpx
            r = np.abs(kap - kp - M)[5:-5].max() / max(np.abs(kap).max(), 1e-9)
            res = max(res, r)
        good = res < 0.01
        ok &= good
        lines.append('  A beam equation residual (curvature of the truth vs pneumatic + load moment): %.2e of max '
                     'curvature  %s' % (res, 'ok' if good else 'FAIL'))
    # --- B/C/D on frames first, middle, last
    W, H = s['W'], s['H']
    ro0 = s['od'] / 2 / um
    ro_max = max(s['od'], s['od_tip']) / 2 / um
    bres, hres, cres, cinfo = [], [], [], []
    for f in sorted({0, n // 2, n - 1}):
        P, S = math_pts(cl[f], um)
        L = S[-1]
        # B. body coverage vs independent raster of the truth
        mk, _, _ = render_linear(s, f, twin=True, look_override=dict(kind='mask'))
        M = apply_flip(s, mk['M'])
        Hm = apply_flip(s, mk['H'])
        seed = np.zeros((H, W), bool)
        pr = np.clip(np.rint(-P[:, 1]).astype(int), 0, H - 1)
        pc = np.clip(np.rint(P[:, 0]).astype(int), 0, W - 1)
        seed[pr, pc] = True
        cand = ndimage.distance_transform_edt(~seed) < ro_max + 3
        Rm = raster_truth(s, P, S, cand)
        rr, cc = np.mgrid[0:H, 0:W]
        tree = cKDTree(P)
        Q = np.stack([cc[cand].astype(float), -rr[cand].astype(float)], 1)
        sf, dd, _, _ = seg_foot(P, S, Q, tree)
        sfull = np.full((H, W), np.nan)
        sfull[cand] = sf

        def stats(sel):
            a1, a2 = M[sel].sum(), Rm[sel].sum()
            c1 = np.array([(M[sel] * cc[sel]).sum(), (M[sel] * rr[sel]).sum()]) / max(a1, 1e-9)
            c2 = np.array([(Rm[sel] * cc[sel]).sum(), (Rm[sel] * rr[sel]).sum()]) / max(a2, 1e-9)
            return a1, a2, float(np.hypot(*(c1 - c2)))
        a1, a2, dc = stats(cand)
        rc_ = s['od_tip'] / 2 / um
        dA = lambda sel: M[sel].sum() - Rm[sel].sum()      # noqa: E731
        # differential estimates: the end region minus an equally long stretch of side edges next to it
        tip_off = (dA(cand & (sfull > L - 3 * rc_)) - dA(cand & (sfull > L - 5 * rc_) & (sfull <= L - 3 * rc_))) \
            / (2 * rc_)
        base_off = (dA(cand & (sfull < 2 * ro0)) - dA(cand & (sfull >= 2 * ro0) & (sfull < 4 * ro0))) / (2 * ro0)
        bres.append((f, (a1 - a2) / (2 * L), dc, tip_off, base_off, np.abs(M - Rm).max()))
        # D. holder
        if s['holder']:
            th = math.atan2(P[1, 1] - P[0, 1], P[1, 0] - P[0, 0])
            B = P[0]
            u = (cc - B[0]) * math.cos(th) + (-rr - B[1]) * math.sin(th)
            v = -(cc - B[0]) * math.sin(th) + (-rr - B[1]) * math.cos(th)
            h = s['holder']
            Rw = (h.get('hw', 2.3) if h['kind'] == 'clamp' else h.get('Rg', 1.5) + h.get('slope', 0) * 30) * ro0
            hc = (u > -30) & (u < 6) & (np.abs(v) < Rw + 3)
            Hr = holder_raster(s, B, th, hc)
            R0 = (h.get('hw', 2.3) if h['kind'] == 'clamp' else h.get('Rg', 1.5)) * ro0
            dH = Hm - Hr
            # the end face: a strip across the holder that keeps 1 px away from its side edges
            strip = hc & (u > -8) & (np.abs(v) < R0 - 1.0)
            face = dH[strip].sum() / (2 * (R0 - 1.0))
            lat = (dH[hc] * v[hc]).sum() / max(Hr[hc].sum(), 1e-9)
            hres.append((f, face, lat))
        # C. optics centring on a clean concentric-lumen twin with the scene's look
        look = s['look']
        for which in ('twin', 'scene'):
            img, _, _ = render_linear(s, f, twin=(which == 'twin'), clean=True, local=(which == 'twin'))
            img = apply_flip(s, img)
            bgv = look.get('bg', 1.0) if look['kind'] in ('df', 'fluor') else 1.0
            w_img = np.abs(img - bgv)
            sig = s['psf']
            reach = ro_max + 3 * sig + 3
            seg = np.diff(P, axis=0)
            phi = np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))
            Sm = (S[1:] + S[:-1]) / 2
            SW = 2.5                # Gaussian window along the tube (px)
            s_start = 3 * ro0 + 3 * sig + (2 * ro0 if s['holder'] else 0) + 3 * SW
            kap_s = np.diff(phi) / np.diff(Sm)
            Sk = (Sm[1:] + Sm[:-1]) / 2
            vals = []
            for s0 in np.arange(s_start, L - 3 * ro_max - 3 * SW, max(2.0, ro0 / 2)):
                k0 = int(np.searchsorted(S, s0))
                P0 = P[k0]
                near = tree.query_ball_point(P0, reach + ro_max + 2 + 3 * SW)
                if any(abs(S[j] - s0) > reach + 2 * ro_max + 4 + 6 * SW for j in near):
                    continue            # another part of the tube is near (crossing / close pass)
                rw = reach + 3 * SW
                if not (rw + 2 < P0[0] < W - 1 - rw - 2 and rw + 2 < -P0[1] < H - 1 - rw - 2):
                    continue
                if s['holder']:
                    th = math.atan2(P[1, 1] - P[0, 1], P[1, 0] - P[0, 0])
                    uu = (P0[0] - P[0, 0]) * math.cos(th) + (P0[1] - P[0, 1]) * math.sin(th)
                    vv = -(P0[0] - P[0, 0]) * math.sin(th) + (P0[1] - P[0, 1]) * math.cos(th)
                    Rh = (s['holder'].get('hw', 2.3) if s['holder']['kind'] == 'clamp' else
                          s['holder'].get('Rg', 1.5) + s['holder'].get('slope', 0) * max(-uu, 0) / ro0) * ro0
                    if uu < rw and abs(vv) < Rh + rw:
                        continue
                r0_, r1_ = int(-P0[1] - rw - 2), int(-P0[1] + rw + 3)
                c0_, c1_ = int(P0[0] - rw - 2), int(P0[0] + rw + 3)
                sub_r, sub_c = np.mgrid[r0_:r1_, c0_:c1_]
                Qs = np.stack([sub_c.ravel().astype(float), -sub_r.ravel().astype(float)], 1)
                sfo, dfo, _, _ = seg_foot(P, S, Qs, tree)
                keep = (np.abs(sfo - s0) <= 3 * SW) & (np.abs(dfo) <= reach)
                kap = np.interp(sfo[keep], Sk, kap_s)
                wv = (w_img[sub_r.ravel()[keep], sub_c.ravel()[keep]] * np.exp(-0.5 * ((sfo[keep] - s0) / SW) ** 2)
                      / (1 - kap * dfo[keep]))
                vals.append((wv * dfo[keep]).sum() / wv.sum())
                if DEBUG_C and which == "twin":
                    print("C", f, round(s0, 1), round(vals[-1], 4), keep.sum())
            if which == 'twin':
                cres.extend(vals)
            else:
                cinfo.extend(vals)
    b = np.array([r[1:] for r in bres])
    # limits: a few times the sampling noise of 64 samples per edge pixel (render and raster)
    good = (np.abs(b[:, 0]).max() < 0.01 and b[:, 1].max() < 0.03 and np.abs(b[:, 2]).max() < 0.03
            and np.abs(b[:, 3]).max() < 0.03 and b[:, 4].max() < 0.15)
    ok &= good
    lines.append('  B body (coverage vs independent raster of the truth, frames %s): mean edge offset %.4f px, '
                 'centroid %.4f px, tip offset %.4f px, base offset %.4f px, max pixel diff %.3f  %s'
                 % ([r[0] for r in bres], np.abs(b[:, 0]).max(), b[:, 1].max(), np.abs(b[:, 2]).max(),
                    np.abs(b[:, 3]).max(), b[:, 4].max(), 'ok' if good else 'FAIL'))
    if hres:
        hh = np.array([r[1:] for r in hres])
        good = np.abs(hh).max() < 0.02
        ok &= good
        lines.append('  D holder: end face vs truth base %.4f px (max), holder axis lateral %.4f px  %s'
                     % (np.abs(hh[:, 0]).max(), np.abs(hh[:, 1]).max(), 'ok' if good else 'FAIL'))
    if cres:
        a = np.abs(np.array(cres))
        good = np.median(a) <= 0.03 and np.quantile(a, 0.95) <= 0.08 and a.max() <= 0.15
        ok &= good
        lines.append('  C optics (clean concentric-lumen twin, local %s look, %d stations): |intensity centroid - '
                     'truth| median %.4f, p95 %.4f, max %.4f px  %s; the clean scene itself (eccentric lumen, full '
                     'optics): signed median %+.3f px' % (s['look']['kind'], len(a), np.median(a), np.quantile(a, 0.95), a.max(),
                                   'ok' if good else 'FAIL', float(np.median(cinfo)) if cinfo else float('nan')))
    else:
        lines.append('  C optics: no usable stations')
    # --- E. frames on disk
    fr = read_frames(s, d)
    good = len(fr) == n and all(a.shape == (H, W) for a in fr)
    msgs = ['%d frames read (%s)' % (len(fr), s['fmt']['kind'])]
    if good:
        m = n // 2
        ref = {}
        for f in sorted({0, max(m - 1, 0), m, min(m + 1, n - 1), n - 1}):
            img, _, _ = render_linear(s, f)
            ref[f] = apply_flip(s, camera(s, img, f)).astype(float)
        if s['fmt']['kind'] in LOSSLESS:
            same = all(np.array_equal(fr[f].astype(float), ref[f]) for f in ref)
            good &= same
            msgs.append('bit-identical to a re-render: %s' % same)
        else:
            rng_ = 255.0
            errs = {f: np.abs(fr[f].astype(float) - ref[f]).mean() / rng_ for f in ref}
            good &= max(errs.values()) < 0.03
            msgs.append('mean |read - re-render| %.2f %% of range' % (100 * max(errs.values())))
        if m - 1 >= 0 and m + 1 < n:
            dm = {f: np.abs(fr[m].astype(float) - ref[f]).mean() for f in (m - 1, m, m + 1)}
            order = dm[m] < dm[m - 1] and dm[m] < dm[m + 1]
            good &= order
            msgs.append('middle frame closest to its own render: %s' % order)
    ok &= good
    lines.append('  E files: ' + '; '.join(msgs) + ('  ok' if good else '  FAIL'))
    mg = meta['derived']['min_margin_px']
    good = mg >= 3
    ok &= good
    lines.append('  F placement: body >= %.1f px inside the frame (border entry excluded); crossing itself in '
                 'frames %s, the holder in frames %s  %s' % (
                     mg, _ranges(meta['derived']['frames_crossing_itself']),
                     _ranges(meta['derived']['frames_crossing_holder']), 'ok' if good else 'FAIL'))
    return ok, lines


def _ranges(v):
    if not v:
        return 'none'
    out, a = [], v[0]
    for x, y in zip(v, v[1:] + [None]):
        if y != x + 1:
            out.append('%d' % a if a == x else '%d-%d' % (a, x))
            a = y
    return ','.join(out)


def _check_one(s):
    t0 = time.time()
    ok, lines = check_scene(s)
    lines[0] += '  (%.1f s)  %s' % (time.time() - t0, 'PASS' if ok else 'FAIL')
    return ok, lines


def check_main(scenes, full, j=2):
    lines = ['alien7 self-checks', '', 'Conventions:']
    ok = check_conventions(lines)
    lines.append('')
    with ProcessPoolExecutor(j) as ex:
        res = list(ex.map(_check_one, scenes))
    for o, ls in res:
        ok &= o
        lines.extend(ls)
    npass = sum(o for o, _ in res)
    lines.append('')
    lines.append('%d/%d scenes pass%s' % (npass, len(res), '' if ok else '; SOME CHECKS FAILED'))
    txt = '\n'.join(lines)
    print(txt)
    if full:
        with open(os.path.join(HERE, 'check_report.txt'), 'w') as fh:
            fh.write(txt + '\n')
    return 0 if ok else 1


def main(argv=None):
    ap = argparse.ArgumentParser(description='render the alien7 scenes')
    ap.add_argument('-j', type=int, default=2)
    ap.add_argument('--only', nargs='*')
    ap.add_argument('--list', action='store_true')
    ap.add_argument('--plan', action='store_true')
    ap.add_argument('--check', action='store_true')
    a = ap.parse_args(argv)
    scenes = scene_list()
    if a.only:
        names = {sc['name'] for sc in scenes}
        bad = set(a.only) - names
        if bad:
            sys.exit('unknown scene(s): ' + ', '.join(sorted(bad)))
        scenes = [sc for sc in scenes if sc['name'] in a.only]
    if a.list:
        for sc in scenes:
            print('%-32s %s' % (sc['name'], sc['desc']))
        return
    if a.plan:
        for sc in scenes:
            plan(sc)
        return
    if a.check:
        sys.exit(check_main([settings(sc) for sc in scenes], full=not a.only))
    os.makedirs(SCENES_DIR, exist_ok=True)
    t0 = time.time()
    cost = sorted(scenes, key=lambda sc: -sc['n'] * sc['W'] * sc['H'])
    if a.j > 1:
        with ProcessPoolExecutor(a.j) as ex:
            list(ex.map(render_scene, cost))
    else:
        for sc in cost:
            render_scene(sc)
    print('rendered %d scenes in %.0f s' % (len(scenes), time.time() - t0))


if __name__ == '__main__':
    main()

#!/usr/bin/env python
"""alien5 -- an independent synthetic evaluation set for ``microtube track``.

    python render.py [--only NAME ...] [-j 2] [--list]

Renders every scene into ``scenes/<name>/``: the frames (video / TIFF stack / image folder),
``scene.json``, ``truth_tracks.csv``, ``truth_centrelines.csv``.

Written from scratch from the subject's physics; shares no code with the tracker or with
other evaluation renderers.

Geometry (pixel units, "math" frame X = col, Y = -row, so y points up):
  a tube is a chain of exact circular arcs / straight pieces (curvature piecewise constant in
  arc length), preceded by a straight piece that runs back into the holder (or out through the
  image border).  Its body is the union of discs normal to the centreline, radius ro(s) (a round
  cap tapers it as sqrt(Rc^2-(s-(L-Rc))^2) over the last Rc of arc, so the apex is the
  centreline's end), with a lumen of radius ri(s), offset sideways by e(s) (eccentric annulus:
  the wall is thinner on the convex side), closed a wall's thickness (or a solid plug) before
  the end.
Image formation, per super-sample of every pixel near the tube (pixels are area-averaged):
  a vertical ray at in-plane point (s, d) lies in the normal plane at s, so its path lengths
  through wall and lumen are chord differences; transmitted light = exp(-absorbance) times a
  refraction loss 1/(1+(|grad OPL|/NA)^2) (light bent out of the objective's aperture: dark
  rims at every interface); fluorescence = emission proportional to the wall's path length;
  phase contrast = OPL minus its low-passed copy (dark object, bright halo); DIC = directional
  derivative of the PSF-blurred OPL.  Then PSF blur (Gaussian, a defocus disc, or a blur that
  grows along the tube), camera (Poisson shot noise, read noise, PRNU, column offsets, hot
  pixels, quantisation, optional Bayer mosaic + demosaic, line jitter), burned-in overlays.
"""
import argparse
import json
import math
import os
import shutil
import sys
import time
import zlib
from multiprocessing import Pool

import cv2
import numpy as np

try:
    import tifffile
except ImportError:  # pragma: no cover
    tifffile = None

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE_DIR = os.path.join(HERE, 'scenes')
TWO_PI = 2.0 * math.pi
REFINE_SS = None
REFINE_RANGE = 0.06      # refine pixels whose super-samples of T differ by more than this


# =============================================================================== geometry
class Seg:
    """Arc (k != 0) or straight piece starting at (x0, y0) with heading th0 (rad, CCW, y up)."""

    def __init__(self, x0, y0, th0, k, length, s0, kind):
        self.x0, self.y0, self.th0, self.k, self.l, self.s0, self.kind = (
            float(x0), float(y0), float(th0), float(k), float(length), float(s0), kind)
        if abs(self.k) > 1e-12:
            self.cx = self.x0 - math.sin(self.th0) / self.k
            self.cy = self.y0 + math.cos(self.th0) / self.k
            self.phi0 = math.atan2(self.y0 - self.cy, self.x0 - self.cx)
            self.R = 1.0 / abs(self.k)

    def point(self, u):
        u = np.asarray(u, float)
        if abs(self.k) <= 1e-12:
            return (self.x0 + u * math.cos(self.th0), self.y0 + u * math.sin(self.th0))
        th = self.th0 + self.k * u
        return (self.x0 + (np.sin(th) - math.sin(self.th0)) / self.k,
                self.y0 - (np.cos(th) - math.cos(self.th0)) / self.k)

    def feet(self, X, Y):
        """All (u, d) with the foot of (X, Y) on this piece's line/circle; d > 0 on the left."""
        if abs(self.k) <= 1e-12:
            c, s = math.cos(self.th0), math.sin(self.th0)
            dx, dy = X - self.x0, Y - self.y0
            return [(dx * c + dy * s, -dx * s + dy * c)]
        sg = 1.0 if self.k > 0 else -1.0
        vx, vy = X - self.cx, Y - self.cy
        rho = np.hypot(vx, vy)
        phi = np.arctan2(vy, vx)
        u = np.mod(sg * (phi - self.phi0), TWO_PI) * self.R
        d = sg * (self.R - rho)
        period = TWO_PI * self.R
        out = [(u, d), (u - period, d)]          # u - period: just before the start
        j = 1
        while j * period < self.l + 2.0:
            out.append((u + j * period, d))
            j += 1
        return out


def chain(base, theta, sections, back_len):
    """Segments of one frame's tube: the straight piece behind the base, then the sections.

    sections: list of (kappa [1/px], length [px]).  Returns (segs, tip (X,Y), tip heading)."""
    bx, by = base
    c, s = math.cos(theta), math.sin(theta)
    segs = [Seg(bx - back_len * c, by - back_len * s, theta, 0.0, back_len, -back_len, 'back')]
    x, y, th, s0 = bx, by, theta, 0.0
    for k, ln in sections:
        g = Seg(x, y, th, k, ln, s0, 'tube')
        segs.append(g)
        x, y = g.point(ln)
        x, y = float(x), float(y)
        th += k * ln
        s0 += ln
    return segs, (x, y), th


def centreline(segs, s):
    """Exact points at arc lengths s (>= 0) on the tube part of segs."""
    s = np.asarray(s, float)
    X = np.empty_like(s)
    Y = np.empty_like(s)
    tube = [g for g in segs if g.kind == 'tube']
    for i, g in enumerate(tube):
        last = i == len(tube) - 1
        m = (s >= g.s0) & ((s <= g.s0 + g.l) if last else (s < g.s0 + g.l))
        if m.any():
            X[m], Y[m] = g.point(s[m] - g.s0)
    return X, Y


# =============================================================================== scene model
def smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


DEFAULTS = dict(
    W=640, H=480, D_um=400.0, D_px=24.0, L_mm=10.0,
    lumen=0.58, ecc=0.15, fill='water', n_wall=1.41, n_med=1.333,
    fractions=[1.0], ratios=[1.0], ro_steps=None, plug_um=0.0, end='round',
    bend=150.0, rest=0.0, profile=('ramp',), elong=0.0, N=30, fps=10.0,
    heading=0.0, holder=dict(kind='glass', gap=0.04, wall=0.22, taper=0.0),
    anchor=(0.12, 0.5), entry=None, allow_cross=False,
    look='bf', colour=False, tint=(1.0, 1.0, 1.0), illum_rgb=(1.0, 1.0, 1.0),
    a_wall=0.12, a_lumen=0.0, na_g=0.22, psf=0.8, psf_kind='gauss', defocus_tip=None, ss=3,
    phase_k=0.55, phase_halo=0.6, dic_angle=35.0, dic_k=0.35, fl_bg=0.06, fl_lumen=0.0,
    fl_in_holder=0.55, bleach=0.0,
    cam=dict(fw=9000.0, rn=5.0, bits=8, level=0.78, black=6.0),
    bg=dict(vign=0.12, grad=(0.04, -0.03), tex=0.0, grain=0.0, dish=None, bubble=None,
            debris=0, debris_dark=0.6, fpn=0.0, prnu=0.0, hot=0, exposure=None, flicker=0.0),
    bayer=False, interlace=0.0,
    overlay=dict(ts=False, bar=False, cross=False),
    fmt='avi_mjpg', jpeg_q=92, margin=10.0,
)


def merge(base, kw):
    out = json.loads(json.dumps(base))
    for k, v in kw.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k].update(v)
        else:
            out[k] = v
    return out


def profile_p(prof, N):
    """Pressure fraction p(k) in [0, 1] for frames 0..N-1."""
    k = np.arange(N, dtype=float)
    t = k / max(N - 1, 1)
    kind = prof[0]
    if kind == 'ramp':
        return t
    if kind == 'ease':
        return 0.5 - 0.5 * np.cos(math.pi * t)
    if kind == 'deflate':
        return 1.0 - t
    if kind == 'osc':                    # ('osc', cycles)
        return 0.5 - 0.5 * np.cos(TWO_PI * prof[1] * t)
    if kind == 'updown':
        return 1.0 - np.abs(2 * t - 1)
    if kind == 'fast':                   # ('fast', n_ramp, n_hold): ramp over n_ramp frames
        n_r = prof[1]
        return np.clip(k / n_r, 0, 1) - np.clip((k - n_r - prof[2]) / n_r, 0, 1)
    if kind == 'steps':                  # ('steps', levels...) each held equally long
        lv = np.array(prof[1:], float)
        return lv[np.minimum((t * len(lv)).astype(int), len(lv) - 1)]
    raise ValueError(kind)


class Scene:
    """All settings of one scene plus everything derived (scale, shapes, placement)."""

    def __init__(self, name, cfg):
        self.name = name
        self.c = cfg
        c = cfg
        self.seed = zlib.crc32(name.encode()) & 0x7FFFFFFF
        self.W, self.H, self.N = int(c['W']), int(c['H']), int(c['N'])
        self.um = float(c.get('um') or c['D_um'] / c['D_px'])
        self.Ro = c['D_um'] / 2 / self.um
        self.Ri = self.Ro * c['lumen']
        self.ecc = c['ecc'] * (self.Ro - self.Ri)           # lumen offset magnitude [px]
        self.L0 = c['L_mm'] * 1000.0 / self.um
        self.plug = c['plug_um'] / self.um
        self.round = c['end'] == 'round'
        st = c['ro_steps']
        self.Rc = self.Ro * (st[-1] if st else 1.0) if self.round else 0.0
        n_l = {'water': 1.333, 'air': 1.0, 'oil': 1.47, 'dye': 1.34}[c['fill']]
        self.dn_o = c['n_wall'] - c['n_med']
        self.dn_i = n_l - c['n_wall']
        self.p = profile_p(c['profile'], self.N)
        self.theta = math.radians(c['heading'])
        self.bend_sign = 1.0 if c['bend'] >= 0 else -1.0
        self.sigma_max = max(c['psf'], c['defocus_tip'][1] if c['defocus_tip'] else 0.0,
                             c.get('psf_disc', 0.0) if c['psf_kind'] == 'disc' else 0.0)
        ho = c['holder']
        self.holder = ho['kind']
        if self.holder == 'glass':
            self.Rpi = self.Ro * (1 + ho['gap']) + 0.3
            self.Rpo = self.Rpi + self.Ro * ho['wall']
            self.taper = ho.get('taper', 0.0)
        if self.holder == 'clamp':
            self.H1 = self.Ro * ho.get('h1', 3.0)
            self.H2 = self.Ro * ho.get('h2', 3.0)
        self._shapes()
        self._place()

    # ------------------------------------------------------------------ shapes
    def sections(self, k):
        """[(kappa, length)] in px for frame k (the plug last, straight)."""
        c = self.c
        p = float(self.p[k])
        lam = 1.0 + c['elong'] * p
        Lb = (self.L0 - self.plug) * lam                    # bending part (plug does not stretch)
        fr = np.array(c['fractions'], float)
        fr = fr / fr.sum()
        r = np.array(c['ratios'], float)
        lens = fr * Lb
        # rest curvature uniform on the bending part; pressure part with ratios, scaled so that
        # at p = 1 (with its elongation) the bend reaches c['bend']
        Lb1 = (self.L0 - self.plug) * (1 + c['elong'])
        krest = math.radians(c['rest']) / ((self.L0 - self.plug))
        rest1 = krest * Lb1
        K1 = (math.radians(c['bend']) - rest1) / float((r * fr * Lb1).sum())
        secs = [(krest + K1 * r[i] * p, lens[i]) for i in range(len(r))]
        if self.plug > 0:
            secs.append((0.0, self.plug))
        return secs

    def _shapes(self):
        self.secs = [self.sections(k) for k in range(self.N)]
        self.L = np.array([sum(l for _, l in s) for s in self.secs])
        self.bend = np.array([sum(k * l for k, l in s) for s in self.secs])

    def shape_points(self, k, base, theta, step=2.0):
        segs, tip, _ = chain(base, theta, self.secs[k], 10.0)
        s = np.linspace(0, self.L[k], int(self.L[k] / step) + 2)
        return s, centreline(segs, s)

    # ------------------------------------------------------------------ placement
    def _place(self):
        c = self.c
        W, H = self.W, self.H
        m = c['margin'] + self.Ro + 2.5 * self.sigma_max
        pts = []
        for k in range(self.N):
            s, (X, Y) = self.shape_points(k, (0.0, 0.0), self.theta)
            pts.append(np.stack([s, X, Y], 1))
        P = np.concatenate(pts)
        s, X, Y = P[:, 0], P[:, 1], P[:, 2]
        col, row = X, -Y                                   # relative to base (0,0)
        if c['entry'] is None:
            # base (bc, br) free: m <= bc + col <= W-1-m, m <= br + row <= H-1-m
            lo_c, hi_c = m - col.min(), W - 1 - m - col.max()
            lo_r, hi_r = m - row.min(), H - 1 - m - row.max()
            if lo_c > hi_c or lo_r > hi_r:
                raise ValueError('%s: tube does not fit (%.0f..%.0f, %.0f..%.0f)'
                                 % (self.name, lo_c, hi_c, lo_r, hi_r))
            if c.get('corner'):
                # base on the line from an image corner along the heading: the holder then
                # leaves the field through that corner
                cc0, rr0 = c['corner']
                dc, dr = math.cos(self.theta), -math.sin(self.theta)
                ts = np.linspace(0, math.hypot(W, H), 4000)
                pc, pr = cc0 + ts * dc, rr0 + ts * dr
                ok = (pc >= lo_c) & (pc <= hi_c) & (pr >= lo_r) & (pr <= hi_r)
                if not ok.any():
                    raise ValueError('%s: no base on the corner line' % self.name)
                i = np.nonzero(ok)[0][0]
                bc, br = pc[i], pr[i]
            else:
                ax, ay = c['anchor']
                bc = min(max(ax * (W - 1), lo_c), hi_c)
                br = min(max(ay * (H - 1), lo_r), hi_r)
        else:
            e = c['entry']
            lean = abs(math.sin(self.theta)) if e in ('top', 'bottom') else abs(math.cos(self.theta))
            far = s > (m + 2 * self.Ro) / max(0.15, lean)
            if e in ('left', 'right'):
                bc = -0.5 if e == 'left' else W - 0.5
                cc = bc + col
                ok = (cc[far] >= m).all() and (cc[far] <= W - 1 - m).all()
                if not ok:
                    raise ValueError('%s: tube runs out across its entry side' % self.name)
                lo_r, hi_r = m - row.min(), H - 1 - m - row.max()
                if lo_r > hi_r:
                    raise ValueError('%s: tube does not fit vertically' % self.name)
                br = min(max(c['anchor'][1] * (H - 1), lo_r), hi_r)
            else:
                br = -0.5 if e == 'top' else H - 0.5
                rr = br + row
                ok = (rr[far] >= m).all() and (rr[far] <= H - 1 - m).all()
                if not ok:
                    raise ValueError('%s: tube runs out across its entry side' % self.name)
                lo_c, hi_c = m - col.min(), W - 1 - m - col.max()
                if lo_c > hi_c:
                    raise ValueError('%s: tube does not fit horizontally' % self.name)
                bc = min(max(c['anchor'][0] * (W - 1), lo_c), hi_c)
        self.base = (float(bc), float(-br))                  # (X, Y)
        self.back_len = 2.0 * math.hypot(W, H) + 10
        # union mask of every frame's tube (for overlays / clutter placement)
        um = np.zeros((H, W), np.uint8)
        for k in range(self.N):
            segs, _, _ = chain(self.base, self.theta, self.secs[k], self.back_len)
            draw_band(um, segs, self.Ro + 6, with_back=False)
        self.holder_mask(um, extra=6)
        self.union = um
        self._crossings()

    def _crossings(self):
        """Frames where the tube touches / crosses itself or its holder (for the record)."""
        from scipy.spatial import cKDTree
        self.self_touch, self.holder_touch = [], []
        c, s_ = math.cos(self.theta), math.sin(self.theta)
        rh = {'glass': getattr(self, 'Rpo', 0), 'clamp': max(getattr(self, 'H1', 0),
                                                              getattr(self, 'H2', 0))}.get(self.holder, 0)
        for k in range(self.N):
            s, (X, Y) = self.shape_points(k, self.base, self.theta, step=1.0)
            P = np.stack([X, Y], 1)
            tree = cKDTree(P)
            pairs = tree.query_pairs(2 * self.Ro + 2, output_type='ndarray')
            if len(pairs) and (np.abs(s[pairs[:, 0]] - s[pairs[:, 1]]) > 5 * self.Ro).any():
                self.self_touch.append(k)
            if self.holder != 'none':
                dx, dy = X - self.base[0], Y - self.base[1]
                u = dx * c + dy * s_
                d = -dx * s_ + dy * c
                far = s > 3 * self.Ro + 4
                if (far & (u < self.Ro + 3) & (np.abs(d) < rh + self.Ro + 3)).any():
                    self.holder_touch.append(k)
        if self.holder_touch and not self.c['allow_cross']:
            print('WARNING %s: tube touches its holder on frames %s' % (self.name, self.holder_touch))
        if self.self_touch and not self.c['allow_cross']:
            print('WARNING %s: tube touches itself on frames %s' % (self.name, self.self_touch))

    def holder_mask(self, mask, extra):
        """Draw the holder's footprint into mask."""
        bx, by = self.base
        c, s = math.cos(self.theta), math.sin(self.theta)
        if self.holder == 'none':
            return
        if self.holder == 'glass':
            r0 = self.Rpo + extra
            r1 = self.Rpo + self.taper * self.back_len + extra
            hl = [(0, r0), (-self.back_len, r1)]
            poly = [(u, v) for u, v in hl] + [(u, -v) for u, v in hl[::-1]]
        else:
            poly = [(0, self.H2 + extra), (-self.back_len, self.H2 + extra),
                    (-self.back_len, -self.H1 - extra), (0, -self.H1 - extra)]
        pp = []
        for u, v in poly:
            X = bx + u * c - v * s
            Y = by + u * s + v * c
            pp.append((X, -Y))
        cv2.fillPoly(mask, [np.round(np.array(pp) * 16).astype(np.int32)], 255, cv2.LINE_8, 4)

    def frame_segs(self, k):
        return chain(self.base, self.theta, self.secs[k], self.back_len)

    # ------------------------------------------------------------------ tube radii
    def radii(self, s, k):
        """ro, ro*ro' (d(ro^2)/2ds), ri, ri*ri', e  at arc lengths s (arrays), frame k."""
        L = self.L[k]
        ro = np.full_like(s, self.Ro)
        rrd = np.zeros_like(s)
        steps = self.c['ro_steps']
        if steps:
            # outer radius factor per section; smooth transition over 0.6 Ro centred on joint
            fr = np.array(self.c['fractions'], float)
            fr = fr / fr.sum()
            joints = np.cumsum(fr)[:-1] * (L - self.plug)
            f = np.full_like(s, steps[0])
            df = np.zeros_like(s)
            w = 0.6 * self.Ro
            for j, sj in enumerate(joints):
                x = (s - (sj - w / 2)) / w
                xc = np.clip(x, 0, 1)
                f = f + (steps[j + 1] - steps[j]) * smoothstep(x)
                df = df + (steps[j + 1] - steps[j]) * 6 * xc * (1 - xc) / w
            ro = self.Ro * f
            rrd = ro * self.Ro * df
        if self.round:
            sc = L - self.Rc
            cap = s > sc
            q = np.maximum(self.Rc ** 2 - (s - sc) ** 2, 0.0)
            ro = np.where(cap, np.minimum(np.sqrt(q), ro), ro)
            rrd = np.where(cap, -(s - sc), rrd)
        # lumen: closed a wall's thickness before the end (or before the plug / cap)
        wall = self.Ro - self.Ri
        if self.plug > 0:
            le = L - self.plug
        else:
            le = L - (self.Rc if self.round else wall)
        ri = np.full_like(s, self.Ri)
        rid = np.zeros_like(s)
        sc = le - self.Ri
        capl = s > sc
        q = np.maximum(self.Ri ** 2 - (s - sc) ** 2, 0.0)
        ri = np.where(capl, np.sqrt(q), ri)
        rid = np.where(capl, -(s - sc), rid)
        ri = np.where(s > le, 0.0, ri)
        e = np.full_like(s, -self.bend_sign * self.ecc)     # thin wall on the convex side
        return ro, rrd, ri, rid, e

    def rmax(self):
        r = self.Ro * (max(self.c['ro_steps']) if self.c['ro_steps'] else 1.0)
        if self.holder == 'glass':
            r = max(r, self.Rpo + self.taper * self.back_len)
        if self.holder == 'clamp':
            r = max(r, self.H1, self.H2)
        return r


def draw_band(mask, segs, radius, with_back=True, step=3.0):
    for g in segs:
        if g.kind == 'back' and not with_back:
            continue
        n = max(2, int(g.l / step) + 2)
        u = np.linspace(0, g.l, n)
        X, Y = g.point(u)
        pts = np.stack([X, -Y], 1)
        cv2.polylines(mask, [np.round(pts * 16).astype(np.int32)], False, 255,
                      int(2 * math.ceil(radius) + 1), cv2.LINE_8, 4)


# =============================================================================== optics
class Acc:
    """Per-super-sample accumulators of everything the looks need."""

    NAMES = ('W', 'Lm', 'Rf', 'OPL', 'FACE', 'G', 'O', 'E', 'IN', 'INB', 'GI', 'LUM')

    def __init__(self, n):
        for nm in self.NAMES:
            setattr(self, nm, np.zeros(n, np.float64))


def tube_layer(sc, k, s, d, acc, idx, in_holder):
    """Add one tube layer's contributions at super-samples idx (foot s, offset d)."""
    ro, rrd, ri, rid, e = sc.radii(s, k)
    ins = np.abs(d) < ro
    if not ins.any():
        return
    s, d, ro, rrd, ri, rid, e, idx = (a[ins] for a in (s, d, ro, rrd, ri, rid, e, idx))
    eps = 1e-6 * sc.Ro ** 2
    q = np.maximum(ro * ro - d * d, eps)
    sq = np.sqrt(q)
    ch_o = 2 * sq
    g_d = sc.dn_o * (-2 * d / sq)
    g_s = sc.dn_o * (2 * rrd / sq)
    dl = d - e
    inl = np.abs(dl) < ri
    qi = np.maximum(ri * ri - dl * dl, eps)
    sqi = np.sqrt(qi)
    ch_i = np.where(inl, 2 * sqi, 0.0)
    g_d = g_d + np.where(inl, sc.dn_i * (-2 * dl / sqi), 0.0)
    g_s = g_s + np.where(inl, sc.dn_i * (2 * rid / sqi), 0.0)
    g = np.hypot(g_d, g_s)
    W = ch_o - ch_i
    if in_holder:
        acc.INB[idx] = 1.0
    else:
        acc.IN[idx] = 1.0
    acc.LUM[idx[inl]] = 1.0
    acc.W[idx] += W
    acc.Lm[idx] += ch_i
    acc.Rf[idx] += np.minimum(np.log1p((g / sc.c['na_g']) ** 2), 40.0)
    acc.OPL[idx] += sc.dn_o * ch_o + sc.dn_i * ch_i
    f_em = sc.c['fl_in_holder'] if (in_holder and sc.holder == 'glass') else 1.0
    acc.E[idx] += f_em * (W + sc.c['fl_lumen'] * ch_i)
    if not sc.round and not in_holder:
        # scattering at the cut end face: a thin dark line just inside the face
        wf = 0.9
        x = (sc.L[k] - s) / wf
        acc.FACE[idx] += np.where(x < 3.5, 0.9 * np.exp(-x * x), 0.0)


def holder_layer(sc, u, d, acc, idx):
    """Glass pipette (u <= 0 behind its end face) or opaque clamp, at super-samples idx."""
    behind = u <= 0
    if not behind.any():
        return
    u, d, idx = u[behind], d[behind], idx[behind]
    if sc.holder == 'clamp':
        inside = (d <= sc.H2) & (d >= -sc.H1)
        acc.O[idx[inside]] += 5.0
        acc.GI[idx[inside]] = 1.0
        return
    rpo = sc.Rpo + sc.taper * (-u)
    rpi = np.full_like(u, sc.Rpi)
    ino = np.abs(d) < rpo
    u, d, idx, rpo, rpi = u[ino], d[ino], idx[ino], rpo[ino], rpi[ino]
    eps = 1e-6 * sc.Ro ** 2
    dn_g = 1.52 - sc.c['n_med']
    sq_o = np.sqrt(np.maximum(rpo * rpo - d * d, eps))
    ini = np.abs(d) < rpi
    sq_i = np.sqrt(np.maximum(rpi * rpi - d * d, eps))
    ch = 2 * sq_o - np.where(ini, 2 * sq_i, 0.0)
    g = dn_g * np.abs(-2 * d / sq_o + np.where(ini, 2 * d / sq_i, 0.0))
    acc.G[idx] += ch
    acc.GI[idx[~ini]] = 1.0
    acc.Rf[idx] += np.minimum(np.log1p((g / sc.c['na_g']) ** 2), 40.0)
    acc.OPL[idx] += dn_g * ch
    # the cut end face of the glass scatters: dark line just behind the face, in the glass
    x = -u / 0.9
    acc.FACE[idx] += np.where((x < 3.5) & ~ini, 0.8 * np.exp(-x * x), 0.0)


def _object_pixels(sc, k, segs, Xc, Yc, S):
    """Per-pixel object quantities (area averages over S x S super-samples) at pixels Xc, Yc."""
    n = len(Xc)
    # S x S stratified samples in an 'N-rooks' pattern: every sample has its own column and row
    # offset (S^2 levels each way) so a straight edge parallel to the pixel grid is resolved to
    # 1/S^2 px, not 1/S; the pattern is symmetric under a half turn about the pixel centre
    i, j = np.meshgrid(np.arange(S), np.arange(S), indexing='ij')
    ox = ((i + (j + 0.5) / S) / S - 0.5).ravel()
    oy = ((j + (i + 0.5) / S) / S - 0.5).ravel()
    ns = S * S
    acc = Acc(n * ns)
    smap = np.full(n, -1.0)
    sbest = np.full(n, np.inf)
    pm = 0.75
    rm = sc.rmax()
    band_r = max(rm, sc.Ro * 1.05) + 3 + 3 * sc.sigma_max
    last = [g for g in segs if g.kind == 'tube'][-1]
    rlim = sc.Ro * (max(sc.c['ro_steps']) if sc.c['ro_steps'] else 1.0) + 0.01
    for g in segs:
        keep = np.zeros(n, bool)                 # pixel-level prefilter
        for u, d in g.feet(Xc, Yc):
            keep |= (u >= -pm) & (u <= g.l + pm) & (np.abs(d) <= rlim + pm)
            if g.kind == 'tube':
                ok2 = (u >= 0) & (u <= g.l) & (np.abs(d) < band_r)
                better = ok2 & (np.abs(d) < sbest)
                sbest[better] = np.abs(d[better])
                smap[better] = g.s0 + u[better]
        if g.kind == 'back' and sc.holder == 'clamp':
            continue                             # hidden under the (opaque) clamp
        pix = np.nonzero(keep)[0]
        if len(pix) == 0:
            continue
        idx = (pix[:, None] * ns + np.arange(ns)[None, :]).ravel()
        X = (Xc[pix][:, None] + ox[None, :]).ravel()
        Y = (Yc[pix][:, None] - oy[None, :]).ravel()
        for u, d in g.feet(X, Y):
            hi = (u <= g.l) if g is last else (u < g.l)
            v = (u >= 0) & hi & (np.abs(d) < rlim)
            if v.any():
                tube_layer(sc, k, g.s0 + u[v], d[v], acc, idx[v], g.kind == 'back')
    if sc.holder != 'none':
        back = segs[0]
        u, d = back.feet(Xc, Yc)[0]
        pix = np.nonzero((u - back.l <= pm) & (np.abs(d) <= rm + pm))[0]
        if len(pix):
            idx = (pix[:, None] * ns + np.arange(ns)[None, :]).ravel()
            X = (Xc[pix][:, None] + ox[None, :]).ravel()
            Y = (Yc[pix][:, None] - oy[None, :]).ravel()
            u, d = back.feet(X, Y)[0]
            holder_layer(sc, u - back.l, d, acc, idx)
    c = sc.c
    mu_w = c['a_wall'] / (2 * sc.Ro)
    mu_l = c['a_lumen'] / (2 * sc.Ro)
    A_common = acc.Rf + acc.FACE + acc.O + 0.01 / (2 * sc.Ro) * acc.G

    def pm_(v):
        return v.reshape(n, ns).mean(1)

    out = {}
    if c['colour']:
        out['T'] = np.stack([pm_(np.exp(-(A_common + c['tint'][ch] * (mu_w * acc.W + mu_l * acc.Lm))))
                             for ch in range(3)], 1)
    else:
        out['T'] = pm_(np.exp(-(A_common + mu_w * acc.W + mu_l * acc.Lm)))
    blk = np.exp(-acc.O)
    out['E'] = pm_(acc.E * blk + 0.03 * acc.G) / (2 * sc.Ro)
    out['BLK'] = pm_(blk)
    out['OPL'] = pm_(acc.OPL) / (2 * sc.Ro * sc.dn_o)
    out['TA'] = pm_(np.exp(-(mu_w * acc.W + acc.O + 0.15 * acc.FACE)))
    # steep pixels (inside the refraction rims) are refined too
    Tg = np.exp(-(A_common + mu_w * acc.W + mu_l * acc.Lm)).reshape(n, ns)
    edge = (Tg.max(1) - Tg.min(1)) > REFINE_RANGE
    if c['look'] != 'bf':
        for v in (acc.E / (2 * sc.Ro), acc.OPL / (2 * sc.Ro * sc.dn_o)):
            v = v.reshape(n, ns)
            edge |= (v.max(1) - v.min(1)) > REFINE_RANGE
    for nm in ('IN', 'INB', 'GI', 'LUM'):
        v = pm_(getattr(acc, nm))
        if nm != 'LUM':
            out[nm] = v
        edge |= (v > 0) & (v < 1)
    out['SMAP'] = smap
    out['EDGE'] = edge
    return out


def render_object(sc, k, ss=None, want=None):
    """Area-averaged object maps near the tube for frame k.

    Returns dict of full-frame float32 maps: T (transmission, (H,W) or (H,W,3)), E (emission),
    OPL (normalised optical path), TA (absorption-only transmission), BLK (opaque blocking),
    IN / INB / GI (area covered by the tube / the tube inside its holder / the holder), SMAP
    (arc length of the nearest tube foot, -1 elsewhere).  want: the names to return (default:
    what the scene's look needs -- full-frame maps of big frames cost memory)."""
    W, H = sc.W, sc.H
    if want is None:
        want = {'bf': {'T'}, 'fluor': {'E', 'BLK'}, 'phase': {'OPL', 'TA'},
                'dic': {'OPL', 'TA'}}[sc.c['look']]
        if sc.c['defocus_tip']:
            want = want | {'SMAP'}
    segs, _, _ = sc.frame_segs(k)
    mask = np.zeros((H, W), np.uint8)
    draw_band(mask, segs, sc.Ro * 1.1 + 3 + 3 * sc.sigma_max)
    if sc.holder != 'none':
        sc.holder_mask(mask, extra=3)
    rows, cols = np.nonzero(mask)
    S = int(ss or sc.c['ss'])
    chunk = max(256, 100000 // (S * S))
    parts = []
    for i in range(0, len(rows), chunk):
        parts.append(_object_pixels(sc, k, segs, cols[i:i + chunk].astype(float),
                                    -rows[i:i + chunk].astype(float), S))
    # adaptive anti-aliasing: pixels that straddle a surface (outer wall, lumen, glass, clamp,
    # end face) are sampled again, much finer -- the refraction rims make these hard edges
    S2 = int(REFINE_SS or min(16, max(8, 2 * S)))
    if S > 1 and parts:
        edge = np.concatenate([p['EDGE'] for p in parts])
        ei = np.nonzero(edge)[0]
        ch2 = max(64, 100000 // (S2 * S2))
        fine = [_object_pixels(sc, k, segs, cols[ei[i:i + ch2]].astype(float),
                               -rows[ei[i:i + ch2]].astype(float), S2)
                for i in range(0, len(ei), ch2)]
        if fine:
            merged = {}
            for nm in parts[0]:
                a = np.concatenate([p[nm] for p in parts])
                if nm not in ('SMAP', 'EDGE'):
                    a[ei] = np.concatenate([f[nm] for f in fine])
                merged[nm] = a
            parts = [merged]
    init = dict(T=1.0, E=0.0, BLK=1.0, OPL=0.0, TA=1.0, IN=0.0, INB=0.0, GI=0.0, SMAP=-1.0)
    out = {}
    for nm, v0 in init.items():
        if nm not in want:
            continue
        shape = (H, W, 3) if (nm == 'T' and sc.c['colour']) else (H, W)
        M = np.full(shape, v0, np.float32)
        if parts:
            M[rows, cols] = np.concatenate([p[nm] for p in parts])
        out[nm] = M
    return out


def gauss(img, sigma):
    if sigma <= 0.05:
        return img
    return cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)


def psf_apply(sc, img, smap=None):
    c = sc.c
    if c['defocus_tip']:
        s0, s1 = c['defocus_tip']                  # sigma at the base, at the tip
        L = float(sc.L.max())
        sig = np.where(smap >= 0, s0 + (s1 - s0) * np.clip(smap / L, 0, 1) ** 1.5, s0)
        levels = np.linspace(s0, s1, 6)
        blurred = [gauss(img, sl) for sl in levels]
        pos = np.interp(sig, levels, np.arange(len(levels)))
        i0 = np.clip(np.floor(pos).astype(int), 0, len(levels) - 2)
        w = (pos - i0).astype(np.float32)
        stack = np.stack(blurred, 0)
        if img.ndim == 3:
            w = w[..., None]
        r, cc = np.indices(sig.shape)
        a = stack[i0, r, cc]
        b = stack[i0 + 1, r, cc]
        return a * (1 - w) + b * w
    if c['psf_kind'] == 'disc':
        rad = c['psf_disc']
        n = int(math.ceil(rad)) + 1
        yy, xx = np.mgrid[-n:n + 1, -n:n + 1]
        ker = np.zeros_like(xx, np.float64)
        S = 8
        for a in range(S):
            for b in range(S):
                ker += (np.hypot(xx + (a + 0.5) / S - 0.5, yy + (b + 0.5) / S - 0.5) <= rad)
        ker /= ker.sum()
        img = cv2.filter2D(img, -1, ker.astype(np.float32), borderType=cv2.BORDER_REFLECT)
        return gauss(img, c['psf'])
    return gauss(img, c['psf'])


# =============================================================================== background
def smooth_noise(rng, H, W, sigma):
    n = rng.standard_normal((H, W)).astype(np.float32)
    n = gauss(n, sigma)
    return n / (n.std() + 1e-12)


class Background:
    """Static and per-frame scene clutter, illumination and camera defects."""

    def __init__(self, sc):
        self.sc = sc
        c = sc.c
        b = c['bg']
        H, W = sc.H, sc.W
        rng = np.random.default_rng(sc.seed + 1)
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
        xn = (xx - W / 2) / (W / 2)
        yn = (yy - H / 2) / (H / 2)
        r2 = (xn ** 2 + yn ** 2) / 2
        self.illum = ((1 - b['vign'] * r2) * (1 + b['grad'][0] * xn + b['grad'][1] * yn)
                      ).astype(np.float32)
        A = np.zeros((H, W), np.float32)           # static absorbance of the clutter
        free = cv2.distanceTransform((sc.union == 0).astype(np.uint8), cv2.DIST_L2, 5)
        self.free = free
        if b['tex'] > 0:                           # out-of-focus particles on the slide
            nb = int(b['tex'] * H * W / 4000)
            for _ in range(nb):
                x, y = rng.uniform(0, W), rng.uniform(0, H)
                sg = rng.uniform(2, 12) * max(1.0, sc.Ro / 15)
                a = rng.uniform(-0.015, 0.05)
                self._blob(A, x, y, sg, a)
        if b['grain'] > 0:                         # agar / coverslip grain
            A += b['grain'] * (0.7 * smooth_noise(rng, H, W, 1.2) + 0.5 * smooth_noise(rng, H, W, 4))
        if b['dish']:
            A += self._dish(rng, free, b['dish'])
        if b['bubble']:
            A += self._bubble(rng, free, b['bubble'])
        self.A_static = A
        del self.free
        self.debris = []
        for _ in range(b['debris']):
            self.debris.append(dict(x=rng.uniform(0, W), y=rng.uniform(0, H),
                                    vx=rng.uniform(-2.5, 2.5), vy=rng.uniform(-2.5, 2.5),
                                    sg=rng.uniform(0.8, 2.2), a=rng.uniform(0.3, 1.0) * b['debris_dark']))
        self.prnu = (1 + b['prnu'] * rng.standard_normal((H, W))).astype(np.float32)
        self.colfpn = (b['fpn'] * rng.standard_normal(W)).astype(np.float32)
        nh = int(b['hot'])
        self.hot = (rng.integers(0, H, nh), rng.integers(0, W, nh), rng.uniform(0.3, 1.0, nh))

    @staticmethod
    def _blob(A, x, y, sg, a):
        H, W = A.shape
        r = int(3 * sg) + 1
        x0, x1 = max(0, int(x) - r), min(W, int(x) + r + 1)
        y0, y1 = max(0, int(y) - r), min(H, int(y) + r + 1)
        if x0 >= x1 or y0 >= y1:
            return
        yy, xx = np.mgrid[y0:y1, x0:x1]
        A[y0:y1, x0:x1] += a * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * sg * sg))

    def _dish(self, rng, free, spec):
        """The curved wall of a dish / well: a big circle cutting off a corner of the field."""
        sc = self.sc
        H, W = sc.H, sc.W
        best = None
        for corner in ((0, 0), (W - 1, 0), (0, H - 1), (W - 1, H - 1)):
            for depth in (0.22, 0.17, 0.12, 0.08):
                Rd = 2.5 * max(W, H)
                cx0 = corner[0] + (-1 if corner[0] == 0 else 1) * 0.0
                dx = -1 if corner[0] == 0 else 1
                dy = -1 if corner[1] == 0 else 1
                dirn = np.array([dx, dy], float) / math.sqrt(2)
                # circle centre beyond the corner so the arc passes 'depth' of the diagonal in
                cpt = np.array(corner, float) - dirn * depth * math.hypot(W, H)
                cen = cpt + dirn * Rd
                yy, xx = np.mgrid[0:H, 0:W]
                rr = np.hypot(xx - cen[0], yy - cen[1])
                line = np.abs(rr - Rd) < 4
                if not line.any():
                    continue
                mind = free[line].min()
                if mind > 25 and (best is None or depth > best[0]):
                    best = (depth, cen, Rd)
                    break
        if best is None:
            return np.zeros((H, W), np.float32)
        _, cen, Rd = best
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
        dist = Rd - np.hypot(xx - cen[0], yy - cen[1])      # > 0 beyond the wall (the corner)
        w = spec.get('w', 5.0)
        A = spec.get('a', 1.0) * np.exp(-(dist / w) ** 2) - 0.12 * np.exp(-((dist + 2.5 * w) / (1.5 * w)) ** 2)
        A += spec.get('beyond', 0.35) * smoothstep((dist - w) / (3 * w))
        self.dish_info = dict(centre=[float(cen[0]), float(cen[1])], radius=float(Rd))
        return A.astype(np.float32)

    def _bubble(self, rng, free, spec):
        sc = self.sc
        H, W = sc.H, sc.W
        Rb = spec.get('r', 30.0)
        fr = free.copy()
        fr[:int(Rb + 12)] = 0
        fr[-int(Rb + 12):] = 0
        fr[:, :int(Rb + 12)] = 0
        fr[:, -int(Rb + 12):] = 0
        cand = np.argwhere(fr > Rb + 20)
        A = np.zeros((H, W), np.float32)
        if len(cand) == 0:
            return A
        y, x = cand[rng.integers(len(cand))]
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
        r = np.hypot(xx - x, yy - y)
        rr = np.clip(r / Rb, 0, 1)
        # a gas bubble: refraction darkens all but a bright centre
        A += np.where(r < Rb, 1.6 * rr ** 4, 0.0) - np.where(r < 0.45 * Rb, 0.15, 0.0)
        A += 1.2 * np.exp(-((r - Rb) / 1.5) ** 2)
        A = gauss(A.astype(np.float32), 0.8)
        self.bubble_info = dict(centre=[float(x), float(y)], radius=float(Rb))
        return A

    def debris_A(self, k):
        A = np.zeros((self.sc.H, self.sc.W), np.float32)
        for p in self.debris:
            self._blob(A, p['x'] + p['vx'] * k, p['y'] + p['vy'] * k, p['sg'], p['a'])
        return A

    def exposure(self, k):
        b = self.sc.c['bg']
        f = 1.0
        if b['exposure']:
            for k0, fac in b['exposure']:
                if k >= k0:
                    f = fac
        if b['flicker']:
            f *= 1 + b['flicker'] * math.sin(2.3 * k + 0.7) * math.cos(0.37 * k)
        return f


# =============================================================================== frames
_BAYER = {}


def bayer_code():
    """The cv2 demosaic code that inverts our RGGB mosaic (checked on a flat colour)."""
    if 'code' in _BAYER:
        return _BAYER['code']
    rgb = np.zeros((16, 16, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 200, 100, 30
    mos = mosaic(rgb)
    best = None
    for nm in ('COLOR_BayerBG2RGB', 'COLOR_BayerGB2RGB', 'COLOR_BayerRG2RGB', 'COLOR_BayerGR2RGB'):
        out = cv2.cvtColor(mos, getattr(cv2, nm))
        err = np.abs(out[4:-4, 4:-4].astype(int) - rgb[4:-4, 4:-4]).mean()
        if best is None or err < best[0]:
            best = (err, nm)
    _BAYER['code'] = getattr(cv2, best[1])
    _BAYER['name'] = best[1]
    return _BAYER['code']


def mosaic(rgb):
    """RGGB mosaic of an RGB image: R at (even,even), G at (even,odd)/(odd,even), B at (odd,odd)."""
    H, W = rgb.shape[:2]
    m = np.empty((H, W), rgb.dtype)
    m[0::2, 0::2] = rgb[0::2, 0::2, 0]
    m[0::2, 1::2] = rgb[0::2, 1::2, 1]
    m[1::2, 0::2] = rgb[1::2, 0::2, 1]
    m[1::2, 1::2] = rgb[1::2, 1::2, 2]
    return m


def linear_frame(sc, bgd, k, clean=False):
    """Linear intensity (bg ~ 1) for frame k, after the optics: (H,W) or (H,W,3) float32."""
    c = sc.c
    obj = render_object(sc, k)
    H, W = sc.H, sc.W
    if clean:
        illum = np.ones((H, W), np.float32)
        Tbg = np.ones((H, W), np.float32)
        expo = 1.0
    else:
        illum = bgd.illum
        Tbg = np.exp(-(bgd.A_static + bgd.debris_A(k))).astype(np.float32)
        expo = bgd.exposure(k)
    look = c['look']
    if look == 'bf':
        if c['colour']:
            col = np.array(c['illum_rgb'], np.float32)
            I = (illum * Tbg)[..., None] * col[None, None, :] * obj['T']
        else:
            I = illum * Tbg * obj['T']
        I = psf_apply(sc, I, obj.get('SMAP'))
    elif look == 'fluor':
        bleach = math.exp(-c['bleach'] * k)
        # excitation field ~ illumination; debris shows dark (absorbs) on the faint background
        E = obj['E'] * bleach
        I = illum * (c['fl_bg'] * Tbg + 0.85 * E) * obj['BLK']
        I = psf_apply(sc, I, obj.get('SMAP'))
        I = I + 0.04 * gauss(I, 6 * max(1.0, sc.Ro / 8))    # out-of-focus haze
        if c['colour']:
            I = I[..., None] * np.array(c['illum_rgb'], np.float32)[None, None, :]
    elif look == 'phase':
        O = obj['OPL']
        halo = O - gauss(O, c['phase_halo'] * sc.Ro)
        I = illum * Tbg * obj['TA'] * np.clip(1 - c['phase_k'] * halo, 0.03, None)
        I = psf_apply(sc, I, obj.get('SMAP'))
    elif look == 'dic':
        O = psf_apply(sc, obj['OPL'], obj.get('SMAP'))
        gy, gx = np.gradient(O)                    # per pixel, along rows / columns
        a = math.radians(c['dic_angle'])           # shear direction, CCW from +x (y up)
        dd = gx * math.cos(a) - gy * math.sin(a)
        # two sheared beams interfere with a quarter-wave bias: I = (1 + sin(phase diff)) / 2,
        # the phase difference ~ the OPL's derivative along the shear
        I = illum * Tbg * obj['TA'] * (0.5 + 0.5 * np.sin(2 * c['dic_k'] * sc.Ro * dd))
    else:
        raise ValueError(look)
    return (I * expo).astype(np.float32), obj


def camera(sc, bgd, I, k, clean=False):
    """Linear intensity -> integer frame as the camera would store it."""
    c = sc.c
    cam = c['cam']
    bits = cam['bits']
    maxdn = (1 << bits) - 1
    rng = np.random.default_rng([sc.seed, 7, k])
    if c['interlace'] and not clean:
        dlt = c['interlace'] * math.sin(1.7 * k + 0.3)
        H, W = I.shape[:2]
        mx = np.tile(np.arange(W, dtype=np.float32), (H, 1))
        sh = np.where(np.arange(H) % 2 == 0, dlt, -dlt).astype(np.float32)
        mx = mx - sh[:, None]
        my = np.tile(np.arange(H, dtype=np.float32)[:, None], (1, W))
        I = cv2.remap(I, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    gain = cam['level'] * maxdn / cam['fw']            # DN per electron
    bayer = c['bayer']
    if bayer:
        I = mosaic(I)
    e = I * cam['fw']
    if not clean:
        e = rng.poisson(np.maximum(e, 0)).astype(np.float32)
        e = e + rng.normal(0, cam['rn'], e.shape).astype(np.float32)
        if e.ndim == 3:
            e = e * bgd.prnu[..., None]
        else:
            e = e * bgd.prnu
    dn = e * gain + cam['black']
    if not clean:
        dn = dn + (bgd.colfpn[None, :, None] if dn.ndim == 3 else bgd.colfpn[None, :])
        r, cc, v = bgd.hot
        if len(r):
            if dn.ndim == 3:
                dn[r, cc, :] = np.maximum(dn[r, cc, :], (v * maxdn)[:, None])
            else:
                dn[r, cc] = np.maximum(dn[r, cc], v * maxdn)
    dn = np.clip(np.rint(dn), 0, maxdn)
    out_dtype = np.uint8 if bits <= 8 else np.uint16
    img = dn.astype(out_dtype)
    if bayer:
        img = cv2.cvtColor(img, bayer_code())           # RGB
    return img


def overlays(sc, img, k, ov_pos):
    ov = sc.c['overlay']
    if not (ov['ts'] or ov['bar'] or ov['cross']):
        return img
    hi = 255 if img.dtype == np.uint8 else int(np.iinfo(img.dtype).max if sc.c['cam']['bits'] > 12
                                                else (1 << sc.c['cam']['bits']) - 1)
    colour = img.ndim == 3
    white = (hi, hi, hi) if colour else hi
    yellow = (hi, hi, 0) if colour else hi
    dark = (0, 0, 0) if colour else 0
    H, W = sc.H, sc.W
    fs = max(0.35, min(W, H) / 900.0)
    th = max(1, int(round(fs * 1.6)))
    if ov['ts']:
        t = k / sc.c['fps']
        txt = '2024-03-%02d 14:%02d:%06.3f  #%04d' % (11, 7 + int(t // 60), t % 60 + 3.5, k + 1)
        x, y = ov_pos['ts']
        for ddx, ddy in ((-1, -1), (1, -1), (-1, 1), (1, 1), (0, 2), (2, 0), (-2, 0), (0, -2)):
            cv2.putText(img, txt, (x + ddx, y + ddy), cv2.FONT_HERSHEY_SIMPLEX, fs, dark, th,
                        cv2.LINE_AA)
        cv2.putText(img, txt, (x, y), cv2.FONT_HERSHEY_SIMPLEX, fs, yellow, th, cv2.LINE_AA)
    if ov['bar']:
        x, y, lpx, label = ov_pos['bar']
        hbar = max(3, int(H / 120))
        cv2.rectangle(img, (x, y), (x + lpx, y + hbar), white, -1)
        cv2.putText(img, label, (x, y - 6), cv2.FONT_HERSHEY_SIMPLEX, fs, white, th, cv2.LINE_AA)
    if ov['cross']:
        cx, cy = W // 2, H // 2
        g = (int(hi * 0.25),) * 3 if colour else int(hi * 0.25)
        cv2.line(img, (0, cy), (W - 1, cy), g, 1, cv2.LINE_8)
        cv2.line(img, (cx, 0), (cx, H - 1), g, 1, cv2.LINE_8)
        for t in range(-5, 6):
            if t == 0:
                continue
            tl = 6 if t % 5 else 12
            cv2.line(img, (cx + t * W // 12, cy - tl), (cx + t * W // 12, cy + tl), g, 1)
            cv2.line(img, (cx - tl, cy + t * H // 12), (cx + tl, cy + t * H // 12), g, 1)
    return img


def overlay_positions(sc):
    """Put text / scale bar in corners the tube never visits."""
    ov = sc.c['overlay']
    H, W = sc.H, sc.W
    fs = max(0.35, min(W, H) / 900.0)
    pos = {}
    occ = sc.union.copy()
    (tw, tht), _ = cv2.getTextSize('2024-03-11 14:07:03.500  #0001', cv2.FONT_HERSHEY_SIMPLEX, fs,
                                   max(1, int(round(fs * 1.6))))
    tw += 4
    corners = lambda w, h: [(8, 8 + h), (W - 8 - w, 8 + h), (8, H - 8), (W - 8 - w, H - 8)]

    def free(x, y, w, h):
        x0, y0 = max(0, x - 4), max(0, y - h - 6)
        x1, y1 = min(W, x + w + 4), min(H, y + 10)
        return not occ[y0:y1, x0:x1].any()

    if ov['ts']:
        for x, y in corners(tw, tht):
            if free(x, y, tw, tht + 4):
                pos['ts'] = (x, y)
                occ[max(0, y - tht - 8):y + 10, max(0, x - 6):x + tw + 6] = 255
                break
        else:
            raise ValueError('%s: no free corner for the timestamp' % sc.name)
    if ov['bar']:
        # a round length in um about 1/6 of the width
        target = W / 6 * sc.um
        nice = [50, 100, 200, 250, 500, 1000, 2000, 5000]
        lum = min(nice, key=lambda v: abs(v - target))
        lpx = int(round(lum / sc.um))
        label = ('%d mm' % (lum // 1000)) if lum >= 1000 else ('%d um' % lum)
        hh = tht + 16
        for x, y in corners(lpx, 4):
            yb = y - 6 if y > H / 2 else y + tht + 6
            if free(x, yb + 6, lpx, hh + 8):
                pos['bar'] = (x, yb, lpx, label)
                break
        else:
            raise ValueError('%s: no free corner for the scale bar' % sc.name)
    return pos


def final_frame(sc, bgd, k, ov_pos, clean=False):
    I, obj = linear_frame(sc, bgd, k, clean)
    img = camera(sc, bgd, I, k, clean)
    if not clean:
        img = overlays(sc, img, k, ov_pos)
    return img, I, obj


# =============================================================================== writing
def to_bgr(img):
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    return cv2.cvtColor(img, cv2.COLOR_RGB2BGR)


class Writer:
    def __init__(self, sc, d):
        self.sc, self.d = sc, d
        f = sc.c['fmt']
        self.fmt = f
        W, H = sc.W, sc.H
        fps = sc.c['fps']
        self.vw = None
        self.tif = None
        if f.startswith('avi') or f in ('mp4', 'mkv', 'mkv_xvid'):
            name, fcc, colour = {
                'avi_mjpg': ('video.avi', 'MJPG', True), 'avi_ffv1': ('video.avi', 'FFV1', None),
                'avi_y800': ('video.avi', 'Y800', False), 'avi_hfyu': ('video.avi', 'HFYU', True),
                'mp4': ('video.mp4', 'mp4v', True), 'mkv': ('video.mkv', 'FFV1', None),
                'mkv_xvid': ('video.mkv', 'XVID', True)}[f]
            if colour is None:
                colour = bool(sc.c['colour'] or sc.c['bayer'])
            self.colour = colour
            self.input = name
            self.vw = cv2.VideoWriter(os.path.join(d, name), cv2.VideoWriter_fourcc(*fcc), fps,
                                      (W, H), isColor=colour)
            if not self.vw.isOpened():
                raise RuntimeError('cannot open writer %s' % f)
            if f == 'avi_mjpg':
                self.vw.set(cv2.VIDEOWRITER_PROP_QUALITY, sc.c['jpeg_q'])
        elif f in ('tif8', 'tif16', 'tifrgb'):
            self.input = 'stack.tif'
            self.tif = tifffile.TiffWriter(os.path.join(d, 'stack.tif'))
        elif f in ('bmp', 'png16', 'jpg_unpadded', 'png8', 'tif_folder'):
            self.input = 'frames'
            os.makedirs(os.path.join(d, 'frames'), exist_ok=True)
        else:
            raise ValueError(f)

    def write(self, k, img):
        f = self.fmt
        if self.vw is not None:
            if self.colour:
                self.vw.write(to_bgr(img))
            else:
                self.vw.write(img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2GRAY))
        elif self.tif is not None:
            self.tif.write(img, photometric='rgb' if img.ndim == 3 else 'minisblack',
                           contiguous=True)
        else:
            fd = os.path.join(self.d, 'frames')
            im = to_bgr(img) if img.ndim == 3 else img
            if f == 'bmp':
                cv2.imwrite(os.path.join(fd, 'img_%03d.bmp' % k), im)
            elif f == 'png16' or f == 'png8':
                cv2.imwrite(os.path.join(fd, 'f%04d.png' % k), im)
            elif f == 'jpg_unpadded':
                cv2.imwrite(os.path.join(fd, 'frame%d.jpg' % (k + 1)), im,
                            [cv2.IMWRITE_JPEG_QUALITY, self.sc.c['jpeg_q']])

    def close(self):
        if self.vw is not None:
            self.vw.release()
        if self.tif is not None:
            self.tif.close()


def truth_rows(sc):
    tr, cl = [], []
    um = sc.um
    for k in range(sc.N):
        segs, tip, th = sc.frame_segs(k)
        L = sc.L[k]
        n = int(math.ceil(L / 0.4)) + 1
        s = np.linspace(0, L, n)
        X, Y = centreline(segs, s)
        bx, by = sc.base
        tr.append(dict(frame=k, time_s=round(k / sc.c['fps'], 6),
                       bend_angle_deg=math.degrees(sc.bend[k]),
                       tip_x_um=tip[0] * um, tip_y_um=tip[1] * um,
                       base_x_um=bx * um, base_y_um=by * um, length_um=L * um, status='ok'))
        for a, b, cc in zip(s, X, Y):
            cl.append((k, a * um, b * um, cc * um))
    return tr, cl


def write_csvs(sc, d):
    tr, cl = truth_rows(sc)
    cols = ['frame', 'time_s', 'bend_angle_deg', 'tip_x_um', 'tip_y_um', 'base_x_um',
            'base_y_um', 'length_um', 'status']
    with open(os.path.join(d, 'truth_tracks.csv'), 'w') as f:
        f.write(','.join(cols) + '\n')
        for r in tr:
            f.write('%d,%.6f,%.6f,%.5f,%.5f,%.5f,%.5f,%.5f,%s\n' % tuple(r[c] for c in cols))
    with open(os.path.join(d, 'truth_centrelines.csv'), 'w') as f:
        f.write('frame,s_um,x_um,y_um\n')
        for r in cl:
            f.write('%d,%.5f,%.5f,%.5f\n' % r)


def scene_json(sc, writer, bgd, ov_pos, d):
    c = sc.c
    meta = dict(
        name=sc.name, description=c['desc'], tests=c.get('tests', ''),
        um_per_px=sc.um, input=writer.input, n_frames=sc.N, fps=c['fps'],
        frame_size=[sc.W, sc.H],
        derived=dict(outer_radius_px=sc.Ro, lumen_radius_px=sc.Ri, lumen_offset_px=sc.ecc,
                     length_px=[float(sc.L.min()), float(sc.L.max())],
                     bend_deg=[float(np.degrees(sc.bend.min())), float(np.degrees(sc.bend.max()))],
                     base_px_col_row=[sc.base[0], -sc.base[1]], base_heading_deg=c['heading'],
                     holder=sc.holder, self_touch_frames=sc.self_touch,
                     holder_touch_frames=sc.holder_touch,
                     pipette_radii_px=([sc.Rpi, sc.Rpo] if sc.holder == 'glass' else None),
                     clamp_halfwidths_px=([sc.H1, sc.H2] if sc.holder == 'clamp' else None),
                     overlay_positions=ov_pos,
                     dish=getattr(bgd, 'dish_info', None), bubble=getattr(bgd, 'bubble_info', None),
                     bayer_demosaic=_BAYER.get('name') if c['bayer'] else None),
        settings=c,
        conventions=dict(
            pixel_centre='pixel (col,row) has its centre at (col,row)',
            axes='x_um = col*um_per_px, y_um = -row*um_per_px (y up)',
            bend='unwrapped CCW rotation of the tip tangent relative to the base tangent (deg)',
            base='where the tube leaves the holder end face; with no holder where the centreline '
                 'crosses the outer pixel edge of the image border',
            tip='physical end: apex of the round cap / centre of the flat end face',
            truth_centrelines='exact points on the arcs, <= 0.4 px apart, base -> tip'),
    )
    with open(os.path.join(d, 'scene.json'), 'w') as f:
        json.dump(meta, f, indent=1, default=lambda o: o.tolist() if hasattr(o, 'tolist') else str(o))


def render_group(names):
    return [render_scene(n) for n in names]


def render_scene(name):
    t0 = time.time()
    cfg = SCENES[name]
    sc = Scene(name, cfg)
    d = os.path.join(SCENE_DIR, name)
    if os.path.exists(d):
        shutil.rmtree(d)
    os.makedirs(d)
    bgd = Background(sc)
    ov_pos = overlay_positions(sc)
    w = Writer(sc, d)
    for k in range(sc.N):
        img, _, _ = final_frame(sc, bgd, k, ov_pos)
        w.write(k, img)
    w.close()
    write_csvs(sc, d)
    scene_json(sc, w, bgd, ov_pos, d)
    return name, time.time() - t0


def load_scene(name):
    sc = Scene(name, SCENES[name])
    bgd = Background(sc)
    return sc, bgd, overlay_positions(sc)


# =============================================================================== the scenes
def S(desc, tests, **kw):
    cfg = merge(DEFAULTS, kw)
    cfg['desc'] = desc
    cfg['tests'] = tests
    return cfg


GLASS_THIN = dict(kind='glass', gap=0.03, wall=0.16, taper=0.0)
GLASS_THICK = dict(kind='glass', gap=0.14, wall=0.85, taper=0.0)
GLASS_TAPER = dict(kind='glass', gap=0.04, wall=0.25, taper=0.004)
NONE = dict(kind='none')


def CLAMP(h1=3.0, h2=3.0):
    return dict(kind='clamp', h1=h1, h2=h2)


SCENES = {
    'bf_basic_mjpg': S(
        'brightfield, thin glass pipette from the left, one section, ramp to 140 deg, MJPG AVI, '
        'timestamp burned in', 'baseline; transmitted look with refraction rims; MJPG artefacts',
        W=720, H=540, bend=140, N=30, heading=0, anchor=(0.1, 0.72), overlay=dict(ts=True),
        fmt='avi_mjpg'),
    'bf_37deg_3sec_ffv1': S(
        'brightfield, pipette from lower left at 37 deg, 3 sections (ratios 1 : 0.4 : 1.8) with '
        'slightly different outer widths, to 210 deg, FFV1 AVI, scale bar',
        'oblique base angle; sections with steps in curvature and width; lossless video',
        W=800, H=600, D_px=22, L_mm=9, fractions=[0.4, 0.35, 0.25], ratios=[1.0, 0.4, 1.8],
        ro_steps=[1.0, 0.94, 0.97], bend=210, N=32, heading=37, anchor=(0.3, 0.75),
        overlay=dict(bar=True), fmt='avi_ffv1'),
    'bf_thickglass_128deg_mp4': S(
        'brightfield, thick-walled glass capillary with visible bore from the lower right '
        '(tube heading 128 deg), 2 sections, inflate/deflate 2 cycles to 160 deg, MP4 (mp4v)',
        'thick holder wider than the tube, its bore visible; oscillation; lossy MP4',
        W=1024, H=768, D_px=26, fractions=[0.6, 0.4], ratios=[1.0, 1.5], bend=160,
        profile=('osc', 2), N=40, heading=128, anchor=(0.75, 0.8), holder=GLASS_THICK, fmt='mp4'),
    'bf_clamp_251deg_tif8_5sec': S(
        'brightfield, opaque dark clamp block from the upper right, tube heading 251 deg, 5 '
        'sections (ratios 1,0.3,1.6,0.8,1.2), curling clockwise to -200 deg, 8-bit multi-page TIFF',
        'opaque holder (no width step, an intensity step); 5 sections; clockwise; TIFF',
        W=720, H=720, D_px=20, L_mm=11, fractions=[0.25, 0.2, 0.2, 0.2, 0.15],
        ratios=[1.0, 0.3, 1.6, 0.8, 1.2], bend=-200, N=28, heading=251, anchor=(0.7, 0.15),
        holder=CLAMP(2.5, 4.0), end='flat', fmt='tif8'),
    'bf_border300_bmp': S(
        'brightfield, no holder: the tube enters across the top border heading 300 deg, bends '
        'clockwise to -120 deg, folder of BMP files',
        'base at the image border at an oblique angle; BMP folder',
        W=640, H=512, D_px=20, L_mm=9, bend=-120, N=24, heading=300, holder=NONE, entry='top',
        anchor=(0.3, 0.0), fmt='bmp'),
    'bf_overcurl_ccw_470': S(
        'brightfield, thin pipette entering from the right (heading 180), 3 sections (1 : 1.5 : '
        '0.7), curling CCW to 470 deg: the tip region sweeps over the base and the pipette, FFV1',
        'over-curl past a full turn; crossing the holder and body; unwrapping',
        W=720, H=600, D_px=18, L_mm=11, fractions=[0.35, 0.35, 0.3], ratios=[1.0, 1.5, 0.7],
        bend=470, N=40, heading=180, anchor=(0.62, 0.42), allow_cross=True, fmt='avi_ffv1'),
    'bf_overcurl_cw_500_colour_mkv': S(
        'halogen colour brightfield, thin pipette from below (heading 90 deg), 5 sections, curling '
        'clockwise to -500 deg (1.39 turns), MKV (FFV1), RGB',
        'clockwise over-curl near 1.4 turns; colour; MKV container',
        W=720, H=720, D_px=18, L_mm=12, fractions=[0.2] * 5, ratios=[0.8, 1.0, 1.3, 0.9, 1.4],
        bend=-500, N=36, heading=90, anchor=(0.55, 0.7), allow_cross=True, colour=True,
        illum_rgb=(1.0, 0.82, 0.55), tint=(0.7, 1.0, 1.4), profile=('ease',), fmt='mkv'),
    'fluor_overcurl_400_png16': S(
        'fluorescence (dyed PDMS wall), weakly autofluorescent glass pipette from the left, 2 '
        'sections, curling to 400 deg, 12-bit camera in a folder of 16-bit PNGs, bleaching',
        'bright look; over-curl; 16-bit PNG with 12-bit levels',
        W=760, H=560, D_px=20, L_mm=10, fractions=[0.5, 0.5], ratios=[1.2, 0.85], bend=400,
        N=36, heading=0, anchor=(0.3, 0.45), allow_cross=True, look='fluor', bleach=0.004,
        cam=dict(bits=12, fw=3000, rn=4, level=0.7, black=100), fmt='png16'),
    'fluor_border_tif16': S(
        'fluorescence, tube entering from the left border heading 15 deg (no holder), bending to '
        '-150 deg, 16-bit multi-page TIFF (full 16-bit range)',
        'bright tube, border base at an angle; 16-bit TIFF',
        W=600, H=480, D_px=18, L_mm=9, bend=-150, N=30, heading=15, holder=NONE, entry='left',
        anchor=(0.0, 0.3), look='fluor', cam=dict(bits=16, fw=20000, rn=8, level=0.7, black=500),
        fmt='tif16'),
    'fluor_clamp_rgb_tif': S(
        'green fluorescence in an RGB TIFF, dark clamp from the bottom (heading 70 deg), flat '
        'end, 2 sections, to 180 deg; the tube emerges from darkness',
        'bright look, RGB TIFF, dark opaque holder; base from where the tube emerges',
        W=640, H=640, D_px=22, L_mm=9, fractions=[0.7, 0.3], ratios=[1.0, 0.6], bend=180,
        N=24, heading=70, anchor=(0.4, 0.95), holder=CLAMP(3.0, 3.0), end='flat', look='fluor',
        colour=True, illum_rgb=(0.15, 1.0, 0.25), fmt='tifrgb'),
    'phase_halo_mp4': S(
        'phase contrast: dark tube with bright halo, thin pipette from the top (heading 270 deg), '
        '2 sections, to -230 deg, MP4',
        'phase look with halo (not brightfield, not fluorescence); base at the top',
        W=640, H=640, D_px=22, L_mm=9, fractions=[0.5, 0.5], ratios=[0.7, 1.3], bend=-230,
        N=30, heading=270, anchor=(0.45, 0.1), look='phase', fmt='mp4'),
    'dic_215deg_avi': S(
        'DIC relief (shear 110 deg), tapered glass pipette from the upper right (heading 215 deg), '
        'one section to 170 deg, MJPG AVI',
        'relief look; oblique base; tapered pipette',
        W=720, H=540, D_px=22, L_mm=9, bend=170, N=28, heading=215, anchor=(0.85, 0.2), dic_angle=110,
        holder=GLASS_TAPER, look='dic', fmt='avi_mjpg'),
    'lowmag_4px_mjpg': S(
        'low magnification: tube 4 px wide (75 um/px), ~160 px long, in 500x400; pipette from the '
        'left; to 200 deg, MJPG',
        'tiny tube at low magnification',
        W=500, H=400, D_um=300, D_px=4.0, L_mm=12, bend=200, N=30, heading=0,
        anchor=(0.35, 0.6), ss=6, psf=0.7, holder=dict(kind='glass', gap=0.05, wall=0.5),
        fmt='avi_mjpg'),
    'lowmag_3px_jpg_unpadded': S(
        'low magnification: tube 3 px wide, 12 mm, brightfield with no holder, entering from the '
        'bottom border heading 100 deg; JPEG folder frame1.jpg .. frame24.jpg (unpadded numbers)',
        'tiny tube; natural sort of frame files; JPEG',
        W=400, H=360, D_um=250, D_px=3.0, L_mm=12, bend=-160, N=24, heading=100, holder=NONE,
        entry='bottom', anchor=(0.5, 1.0), ss=6, psf=0.6, a_wall=0.3, fmt='jpg_unpadded',
        jpeg_q=90),
    'highmag_2048_85px': S(
        'high magnification: 2048x1536, tube 85 px wide (5.3 um/px), 8 mm = 1500 px long, thick '
        'pipette from the left, 2 sections, to 170 deg, MP4',
        'wide tube, large frame, tube length ~ image size',
        W=2048, H=1536, D_um=450, D_px=85, L_mm=8, fractions=[0.55, 0.45], ratios=[1.0, 1.4],
        bend=170, N=16, heading=-8, anchor=(0.08, 0.35), ss=2, psf=1.3,
        holder=dict(kind='glass', gap=0.05, wall=0.3), fmt='mp4'),
    'highmag_1600_45px_plug': S(
        'high magnification 1600x1200, tube 45 px wide, 3 sections + a solid straight plug at a '
        'rounded tip, pipette from the lower left (heading 25 deg), to 160 deg, TIFF8',
        'plug at the tip (straight, solid); rounded cap; corner holder; big frames',
        W=1600, H=1200, D_um=300, D_px=45, L_mm=8, fractions=[0.4, 0.3, 0.3],
        ratios=[1.0, 1.6, 0.7], plug_um=400, bend=160, N=18, heading=25, anchor=(0.1, 0.95),
        ss=3, psf=1.1, fmt='tif8'),
    'fast_inflate_28deg_per_frame': S(
        'fast inflation: 0 -> 330 deg in 12 frames (27.5 deg/frame), held, then back down as fast, '
        'thin pipette from the left, 2 sections, FFV1',
        'big frame-to-frame changes',
        W=640, H=560, D_px=20, L_mm=9, fractions=[0.5, 0.5], ratios=[1.0, 1.3], bend=330,
        profile=('fast', 12, 4), N=28, heading=0, anchor=(0.3, 0.5), allow_cross=True,
        fmt='avi_ffv1'),
    'oscillate_40deg_steps_mkv': S(
        'inflate/deflate cycles: 3 cycles of 0 <-> 240 deg in 15 frames each (up to 50 deg/frame), '
        'pipette from the right, MKV (XVID)',
        'oscillation with big steps; lossy MKV',
        W=640, H=480, D_px=18, L_mm=9, fractions=[0.6, 0.4], ratios=[1.0, 0.7], bend=-240,
        profile=('osc', 3), N=45, heading=180, anchor=(0.85, 0.4), fmt='mkv_xvid'),
    'elongating_4pct': S(
        'tube that elongates by 4 % with pressure (10.0 -> 10.4 mm), thin pipette from the left, '
        'one section, to 220 deg, 8-bit TIFF',
        'changing length; length error',
        W=700, H=560, D_px=20, L_mm=10, bend=220, elong=0.04, N=30, heading=0,
        anchor=(0.25, 0.35), fmt='tif8'),
    'rest_bent_start': S(
        'tube slightly bent at rest (+18 deg at frame 0) then inflated to 175 deg; pipette from '
        'the bottom (heading 90); MJPG',
        'a video that starts bent; base tangent from the holder',
        W=640, H=600, D_px=22, L_mm=9, rest=18, bend=175, N=26, heading=90, anchor=(0.6, 0.95),
        fmt='avi_mjpg'),
    'defocus_tip_gradient': S(
        'out-of-focus tip: PSF sigma grows from 0.8 px at the base to 4.5 px at the tip; pipette '
        'from the left; 2 sections to 160 deg; FFV1',
        'blur increasing along the tube',
        W=640, H=480, D_px=24, L_mm=9, fractions=[0.5, 0.5], ratios=[1.0, 1.2], bend=160,
        N=26, heading=0, anchor=(0.12, 0.75), defocus_tip=[0.8, 4.5], fmt='avi_ffv1'),
    'bayer_demosaic_colour': S(
        'colour camera: RGB rendered, Bayer (RGGB) mosaic, noise on the mosaic, demosaiced with '
        'OpenCV; halogen light; pipette from the left at -20 deg; to 190 deg; HFYU AVI colour',
        'demosaic artefacts and colour noise',
        W=720, H=540, D_px=20, L_mm=9, bend=190, N=26, heading=-20, anchor=(0.12, 0.25),
        colour=True, bayer=True, illum_rgb=(1.0, 0.85, 0.6), tint=(0.8, 1.0, 1.3),
        fmt='avi_hfyu'),
    'interlace_jitter': S(
        'interlaced-ish line jitter: even and odd rows shifted +-0.45 px (varying per frame), '
        'timestamp, pipette from the left, to -170 deg, MJPG',
        'line jitter (comb) on edges',
        W=640, H=480, D_px=20, L_mm=9, bend=-170, N=30, heading=0, anchor=(0.12, 0.3),
        interlace=0.45, overlay=dict(ts=True), fmt='avi_mjpg'),
    'debris_drift_bubble': S(
        'drifting debris particles (some pass over the tube), an air bubble, out-of-focus '
        'particles on the slide; pipette from the left at 10 deg; 2 sections to 200 deg; MP4',
        'moving clutter; bubble',
        W=800, H=600, D_px=20, L_mm=9, fractions=[0.5, 0.5], ratios=[1.0, 1.4], bend=200, N=36,
        heading=10, anchor=(0.12, 0.7), bg=dict(tex=1.0, debris=14, bubble=dict(r=32.0)),
        fmt='mp4'),
    'dish_edge_texture': S(
        'edge of the dish (large dark curved wall) cutting a corner of the field, agar grain and '
        'out-of-focus particles; pipette from the left; to 150 deg; Y800 (uncompressed) AVI',
        'strong non-tube edge in the field; textured background',
        W=800, H=600, D_px=22, L_mm=9, bend=150, N=28, heading=0, anchor=(0.1, 0.55),
        bg=dict(tex=1.5, grain=0.012, dish=dict(a=1.1, w=6.0, beyond=0.4)), fmt='avi_y800'),
    'exposure_fpn_hot_tif16': S(
        'camera defects: exposure steps (x0.7 at frame 10, x1.25 at frame 20), flicker, strong '
        'vignetting, column fixed-pattern noise, PRNU, 150 hot pixels; 12-bit in 16-bit TIFF',
        'time-varying illumination; fixed-pattern noise; hot pixels',
        W=640, H=512, D_px=20, L_mm=9, bend=-210, N=30, heading=0, anchor=(0.12, 0.3),
        cam=dict(bits=12, fw=6000, rn=6, level=0.6, black=64),
        bg=dict(vign=0.45, grad=(0.15, 0.08), fpn=4.0, prnu=0.02, hot=150,
                exposure=[[10, 0.7], [20, 1.25]], flicker=0.03), fmt='tif16'),
    'crosshair_scalebar_ts': S(
        'burned-in reticle crosshair across the whole field, a scale bar and a timestamp; '
        'pipette from the left; to 160 deg; MJPG',
        'overlays crossing the tube; text changing every frame',
        W=640, H=480, D_px=20, L_mm=9, bend=160, N=28, heading=0, anchor=(0.1, 0.72),
        overlay=dict(ts=True, bar=True, cross=True), fmt='avi_mjpg'),
    'corner_holder_315_5sec': S(
        'thin pipette from the top-left corner (heading 315 deg), 5 sections (1,1.7,0.5,1.2,0.8), '
        'flat end, to 240 deg, PNG 8-bit folder',
        'holder from a corner; 5 sections; flat end face',
        W=800, H=800, D_px=20, L_mm=10, fractions=[0.2] * 5, ratios=[1.0, 1.7, 0.5, 1.2, 0.8],
        bend=240, N=30, heading=315, corner=(-0.5, -0.5), end='flat', fmt='png8'),
    'deflate_from_380_clamp': S(
        'deflating from a 380 deg curl to straight; dark clamp from the right (heading 180); '
        '3 sections; the first frame is the most curled; FFV1',
        'starts over-curled (the first frame crosses itself); deflation',
        W=760, H=600, D_px=18, L_mm=10, fractions=[0.4, 0.3, 0.3], ratios=[0.8, 1.4, 1.0],
        bend=380, profile=('deflate',), N=30, heading=180, anchor=(0.9, 0.6),
        holder=CLAMP(2.5, 2.5), allow_cross=True, fmt='avi_ffv1'),
    'long_300_small': S(
        '300 frames of 320x240: slow inflate/deflate (5 cycles to 170 deg), thin pipette from the '
        'left, MJPG; checks nothing drifts',
        'long video; drift',
        W=320, H=240, D_px=10, L_mm=10, bend=170, profile=('osc', 5), N=300, fps=25.0,
        heading=0, anchor=(0.05, 0.75), ss=3, psf=0.7, fmt='avi_mjpg'),
    'eccentric_air_lumen': S(
        'air-filled, strongly eccentric lumen (dark lumen rims off-centre), thick glass holder, '
        'tube heading 160 deg, to -180 deg, HFYU AVI',
        'asymmetric interior: the centreline is the outer edges\' midline, not the lumen\'s',
        W=800, H=600, D_px=28, L_mm=9, lumen=0.5, ecc=0.75, fill='air', bend=-180, N=26,
        heading=160, anchor=(0.85, 0.35), holder=GLASS_THICK, fmt='avi_hfyu'),
    'small_256_fluor': S(
        'small 256x256 frame: fluorescence, tube 8 px wide, pipette from the left, to 250 deg, '
        'low light (shot-noise limited), 8-bit TIFF',
        'small frame; low SNR bright tube',
        W=256, H=256, D_px=8, L_mm=9, bend=250, N=30, heading=0, anchor=(0.25, 0.4),
        look='fluor', psf=0.8, ss=6, cam=dict(fw=600, rn=3, level=0.8, black=4), fmt='tif8'),
    'dic_overcurl_border': S(
        'DIC relief, no holder: tube enters from the right border heading 240 deg, 2 sections, '
        'curling CW to -420 deg, FFV1',
        'relief look with over-curl; border base',
        W=720, H=600, D_px=18, L_mm=10, fractions=[0.5, 0.5], ratios=[1.0, 1.35], bend=-420,
        N=34, heading=240, holder=NONE, entry='right', anchor=(1.0, 0.35), look='dic',
        dic_angle=-50, allow_cross=True, fmt='avi_ffv1'),
    'defocus_disc_lowcontrast': S(
        'defocused (disc PSF r=2.5 px + gauss) low-contrast brightfield (matched index: water-filled '
        'PDMS in oil-like medium), taper pipette from the left, 2 sections, to -190 deg, MJPG q75',
        'weak edges, defocus; JPEG compression',
        W=640, H=480, D_px=22, L_mm=9, fractions=[0.5, 0.5], ratios=[1.0, 0.75], bend=-190,
        N=28, heading=0, anchor=(0.12, 0.25), n_med=1.38, na_g=0.35, psf_kind='disc',
        psf_disc=2.5, psf=0.6, holder=GLASS_TAPER, jpeg_q=75, fmt='avi_mjpg'),
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--only', nargs='*')
    ap.add_argument('-j', type=int, default=2)
    ap.add_argument('--list', action='store_true')
    a = ap.parse_args(argv)
    names = list(SCENES)
    if a.list:
        for n in names:
            print(n)
        return
    if a.only:
        bad = set(a.only) - set(names)
        if bad:
            sys.exit('unknown: ' + ', '.join(sorted(bad)))
        names = [n for n in names if n in a.only]
    os.makedirs(SCENE_DIR, exist_ok=True)
    cost = {n: SCENES[n]['W'] * SCENES[n]['H'] * SCENES[n]['N'] for n in names}
    names.sort(key=lambda n: -cost[n])
    # scenes with frames over 1.5 Mpx run one after the other in one worker, so that two of
    # them never hold memory at once
    big = [n for n in names if SCENES[n]['W'] * SCENES[n]['H'] > 1.5e6]
    groups = ([big] if big else []) + [[n] for n in names if n not in big]
    t0 = time.time()
    if a.j > 1 and len(names) > 1:
        with Pool(a.j, maxtasksperchild=4) as pool:
            for res in pool.imap_unordered(render_group, groups):
                for n, dt in res:
                    print('  %-32s %5.1f s' % (n, dt), flush=True)
    else:
        for n in names:
            print('  %-32s %5.1f s' % render_scene(n), flush=True)
    print('rendered %d scenes in %.0f s' % (len(names), time.time() - t0))


if __name__ == '__main__':
    main()

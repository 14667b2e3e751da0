#!/usr/bin/env python
"""Independent renderer of synthetic microscope videos of bending PDMS microtubes.

Written from scratch for an evaluation set (it shares no code with the tracker).

    python render.py                  # regenerate every scene under scenes/
    python render.py --only NAME ...  # just these
    python render.py --list           # print the scene names and what each tests

Conventions (also written into every scene.json):
  * pixel (col,row) has its centre at (col,row); the top-left pixel's centre is (0,0);
  * geometry is computed in "y-up pixels": X = col, Y = -row;  x_um = X*um, y_um = Y*um;
  * angles are counter-clockwise in that y-up frame; tangent angle phi(s) along the arc;
  * bend angle = phi(tip) - phi(base) (unwrapped, CCW positive, 1.2 turns = +-432 deg);
  * s = 0 is the base, where the tube leaves the holder (or crosses the image border when
    no holder shows: the outer edge of the border pixels, i.e. col -0.5 / row -0.5 /
    col W-0.5 / row H-0.5); s = L is the tube's physical end (apex of a rounded cap, or the
    flat end face), so the truth tip is the centreline's end point and length = L.

Image formation: each tube "layer" (a stretch of tube whose footprint does not overlap
itself) is evaluated analytically at every pixel of its band from the pixel's exact foot
point on the centreline (arcs and straight pieces, so no polyline approximation): lateral
offset n and arc position s.  Radial profiles are box-prefiltered over one pixel (analytic
anti-aliasing) through fine look-up tables.  Where the tube crosses itself a pixel gets one
contribution per layer: absorbances add (transmitted looks), emissions add (fluorescence),
optical path lengths add (phase contrast, DIC).  The holder is super-sampled 4x4.
"""
import argparse
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

ROOT = os.path.dirname(os.path.abspath(__file__))
SCENE_ROOT = os.path.join(ROOT, 'scenes')
TWO_PI = 2.0 * math.pi

# --------------------------------------------------------------------------------------
# scene catalogue
# --------------------------------------------------------------------------------------
DEFAULT = dict(
    W=640, H=480, n_frames=24, fps=10.0,
    look='brightfield',            # brightfield | bright_lumen | phase | dic | fluorescent | opaque
    colour=None,                   # None (grey) or 'halogen' | 'green' | 'cool' | 'warm_fluor'
    L_mm=10.0, D_um=400.0, width_px=20.0,
    lumen_frac=0.6, ecc=0.0,       # lumen radius / outer radius; lumen shift (fraction of R)
    sections=[[1.0, 1.0]],         # [fraction of the bending length, relative curvature]
    plug_w=0.0,                    # straight solid plug at the tip, in tube widths
    cap='round',                   # round | flat
    bend_deg=180.0, bend_start_deg=0.0, ease='linear', hold=2,
    elong=0.0,                     # fractional elongation of the bending part at full bend
    base_angle_deg=0.0,            # base tangent direction (CCW from +x, y up)
    holder_len_w=5.0,              # wanted visible holder length, in tube widths
    perp_shift=0.0,                # -1..1: base position across the axis inside the slack
    holder=dict(kind='pipette', ratio=1.5, wall=0.15, taper=0.0, max_ratio=None,
                contrast=1.0, inner_att=0.6),
    entry=None,                    # with holder kind 'none': 'left'|'right'|'top'|'bottom'
    drift=None,                    # dict(amp=px, angle_deg=..., wobble=px)
    margin=6,
    contrast=1.0,                  # scales the tube's absorption/emission/phase strength
    bg=0.70,
    blur=dict(kind='gauss', sigma=0.9),
    noise=dict(photons=3000.0, read=0.004),
    illum=dict(gx=0.0, gy=0.0, vignette=0.0),
    flicker=0.0, dust=0, fibre=None, scratch=None,
    dic_shear_deg=45.0,
    fieldstop=None, letterbox=None,
    fmt='png',                     # avi | mp4 | png | jpg | tiff16 | tiff12 | tiff8
    quality=90,
    seed=1,
    desc='',
)

SCENES = [
    dict(name='transp_basic', desc='bright-field transmitted tube (dark walls, lighter lumen), '
         'glass pipette 1.5x, single section, 180 deg CCW, MJPG AVI', look='brightfield',
         W=640, H=480, width_px=20, D_um=400, L_mm=10, bend_deg=180, base_angle_deg=0,
         fmt='avi', quality=90, seed=11),
    dict(name='bf_halogen_colour_cw', desc='yellowish halogen bright-field in RGB, 2 sections '
         '(ratio 1.6), clockwise -200 deg, base at the bottom pointing up, PNG colour',
         look='brightfield', colour='halogen', W=800, H=600, width_px=19, D_um=350, L_mm=9,
         sections=[[0.6, 1.0], [0.4, 1.6]], bend_deg=-200, base_angle_deg=90, fmt='png',
         seed=12),
    dict(name='bright_lumen_mp4', desc='transparent tube with a bright (focusing) lumen, '
         'base on the right pointing left, 240 deg, mp4v MP4', look='bright_lumen', W=640,
         H=480, width_px=16, D_um=300, L_mm=9, bend_deg=240, base_angle_deg=180, fmt='mp4',
         holder=dict(kind='pipette', ratio=1.7, wall=0.12), seed=13),
    dict(name='phase_basic_tiff8', desc='phase contrast (dark tube, bright halo), base at the '
         'top pointing down, 160 deg, 8-bit multi-page TIFF', look='phase', W=640, H=480,
         width_px=16, D_um=450, L_mm=11, bend_deg=160, base_angle_deg=-90, fmt='tiff8',
         seed=14),
    dict(name='phase_overcurl_450', desc='phase contrast, 3 sections with decreasing '
         'curvature (outward spiral), 450 deg: the tip crosses the body and the pipette',
         look='phase', W=1024, H=768, width_px=24, D_um=400, L_mm=11,
         sections=[[0.4, 1.4], [0.35, 1.0], [0.25, 0.7]], bend_deg=450, base_angle_deg=10,
         n_frames=32, ease='smooth', fmt='png', seed=15),
    dict(name='fluor_basic_tiff16', desc='fluorescent tube (bright walls) on a dark '
         'background, full-range 16-bit TIFF, base angle 30 deg, -270 deg', look='fluorescent',
         W=512, H=512, width_px=14, D_um=300, L_mm=8, bend_deg=-270, base_angle_deg=30,
         fmt='tiff16', bg=0.05, seed=16,
         holder=dict(kind='pipette', ratio=1.4, wall=0.15, inner_att=0.45, contrast=1.0)),
    dict(name='fluor_lowsnr', desc='fluorescent, low SNR (~25 photons at full scale + read '
         'noise), 200 deg, PNG', look='fluorescent', W=640, H=480, width_px=18, D_um=400,
         L_mm=10, bend_deg=200, base_angle_deg=-20, bg=0.06,
         noise=dict(photons=25.0, read=0.03), blur=dict(kind='gauss', sigma=1.2), fmt='png',
         holder=dict(kind='pipette', ratio=1.5, wall=0.15, inner_att=0.5), seed=17),
    dict(name='fluor_endface_flat', desc='fluorescent tube with a flat cap and a brighter end '
         'face, base on the left-bottom (200 deg axis), 150 deg, JPEG folder q85',
         look='fluorescent', end_glow=1.4, cap='flat', W=800, H=600, width_px=28, D_um=450,
         L_mm=10, bend_deg=150, base_angle_deg=200, fmt='jpg', quality=85, bg=0.04, seed=18,
         holder=dict(kind='pipette', ratio=1.35, wall=0.12, inner_att=0.5)),
    dict(name='colour_green_fluor', desc='green fluorescence in RGB (MJPG AVI), 2 sections, '
         '-320 deg clockwise curl', look='fluorescent', colour='green', W=960, H=720,
         width_px=22, D_um=400, L_mm=11, sections=[[0.5, 0.8], [0.5, 1.2]], bend_deg=-320,
         base_angle_deg=95, fmt='avi', quality=85, bg=0.05, seed=19,
         holder=dict(kind='pipette', ratio=1.6, wall=0.15, inner_att=0.5)),
    dict(name='dic_diag', desc='DIC relief (one flank bright, the other dark, shear -55 deg), '
         'diagonal base at 35 deg, 200 deg, PNG', look='dic', dic_shear_deg=-55, W=800, H=600,
         width_px=21, D_um=350, L_mm=9, bend_deg=200, base_angle_deg=35, fmt='png',
         bg=0.5, seed=20),
    dict(name='dic_overcurl_cw_400', desc='DIC relief, -400 deg clockwise over-curl with an '
         'outward spiral (2 sections) crossing itself, 8-bit TIFF', look='dic',
         dic_shear_deg=-30, W=1024, H=768, width_px=22, D_um=400, L_mm=12,
         sections=[[0.5, 1.3], [0.5, 0.8]], bend_deg=-400, base_angle_deg=-160, fmt='tiff8',
         n_frames=30, ease='smooth', bg=0.5, seed=21),
    dict(name='opaque_small_320', desc='opaque (uniformly dark) tube only ~8 px wide in a '
         '320x240 JPEG folder, 120 deg', look='opaque', W=320, H=240, width_px=8, D_um=300,
         L_mm=9, bend_deg=120, base_angle_deg=-5, fmt='jpg', quality=90, margin=5,
         blur=dict(kind='gauss', sigma=0.7), seed=22,
         holder=dict(kind='pipette', ratio=1.6, wall=0.18)),
    dict(name='sections4_steps', desc='4 sections, curvature steps 1.8x/0.5x/1.9x at the '
         'joints, starts bent (40 deg) and bends to 300 deg, MJPG AVI', look='brightfield',
         W=1024, H=768, width_px=22, D_um=400, L_mm=11,
         sections=[[0.3, 1.0], [0.25, 1.8], [0.25, 0.9], [0.2, 1.7]], bend_start_deg=40,
         bend_deg=300, base_angle_deg=-10, n_frames=30, fmt='avi', quality=90, seed=23),
    dict(name='plug_tip', desc='straight unbending solid plug of 2.5 tube widths at the tip, '
         '2 sections, 220 deg, PNG', look='brightfield', W=800, H=600, width_px=24, D_um=400,
         L_mm=10, plug_w=2.5, sections=[[0.5, 1.0], [0.5, 1.4]], bend_deg=220,
         base_angle_deg=170, fmt='png', seed=24),
    dict(name='elongating', desc='tube elongating by 3 % as it bends (eased ramp), '
         'bright-lumen look, 250 deg', look='bright_lumen', W=800, H=600, width_px=16,
         D_um=350, L_mm=10, elong=0.03, bend_deg=250, ease='smooth', base_angle_deg=-100,
         n_frames=28, fmt='png', seed=25),
    dict(name='deflating', desc='starts bent at 320 deg and unbends to 20 deg (deflation), '
         'phase contrast, TIFF 8-bit', look='phase', W=640, H=480, width_px=16, D_um=350,
         L_mm=10, bend_start_deg=320, bend_deg=20, ease='smooth', base_angle_deg=185,
         sections=[[0.6, 1.0], [0.4, 1.3]], n_frames=26, fmt='tiff8', seed=26),
    dict(name='drift', desc='stage drift of ~5 px plus a wobble (tube and pipette move '
         'together), bright-field, 180 deg, PNG', look='brightfield', W=800, H=600,
         width_px=24, D_um=400, L_mm=10, bend_deg=180, base_angle_deg=5,
         drift=dict(amp=5.0, angle_deg=60.0, wobble=1.5), margin=12, fmt='png', seed=27),
    dict(name='jpeg_q40', desc='heavy JPEG compression (quality 40) in a JPEG folder, '
         'bright-field, 210 deg', look='brightfield', W=640, H=480, width_px=16, D_um=400,
         L_mm=10, bend_deg=210, base_angle_deg=-30, fmt='jpg', quality=40, seed=28),
    dict(name='defocus_disc', desc='defocus: uniform disc blur of radius 3.5 px, bright-field, '
         '160 deg', look='brightfield', W=800, H=600, width_px=22, D_um=450, L_mm=10,
         bend_deg=160, base_angle_deg=80, blur=dict(kind='disc', radius=3.5), margin=10,
         fmt='png', seed=29),
    dict(name='fieldstop', desc='round field stop (black outside a lit disc), bright-field, '
         '200 deg, MJPG AVI', look='brightfield', W=640, H=480, width_px=11, D_um=350,
         L_mm=8, bend_deg=200, base_angle_deg=20, fieldstop=dict(cx=330, cy=236, r=290),
         fmt='avi', quality=90, seed=30),
    dict(name='letterbox', desc='letterbox: black bars of 60 px top and bottom (640x360 '
         'content in a 640x480 frame), bright-field, 150 deg, MP4', look='brightfield',
         W=640, H=480, width_px=13, D_um=300, L_mm=9, bend_deg=150, base_angle_deg=0,
         letterbox=dict(top=60, bottom=60), fmt='mp4', seed=31),
    dict(name='big_2048', desc='2048x1536 halogen colour frames, tube ~72 px wide, 270 deg, '
         'MJPG AVI', look='brightfield', colour='halogen', W=2048, H=1536, width_px=72,
         D_um=480, L_mm=10, bend_deg=270, base_angle_deg=-15, n_frames=16, fmt='avi',
         quality=85, blur=dict(kind='gauss', sigma=1.8), margin=12, seed=32),
    dict(name='tiff16_12bit', desc='16-bit TIFF using only 12 bits (black level 100, max '
         '4095), fluorescent, 1280x1024, -240 deg', look='fluorescent', W=1280, H=1024,
         width_px=36, D_um=480, L_mm=11, bend_deg=-240, base_angle_deg=-60, fmt='tiff12',
         bg=0.06, n_frames=20, blur=dict(kind='gauss', sigma=1.4), seed=33,
         holder=dict(kind='pipette', ratio=1.4, wall=0.14, inner_att=0.5)),
    dict(name='fibre_crossing', desc='a stray dark fibre lying across the tube\'s path, plus '
         'a few dust specks, bright-field, 200 deg', look='brightfield', W=800, H=600,
         width_px=22, D_um=400, L_mm=10, bend_deg=200, base_angle_deg=0, dust=6,
         fibre=dict(at_s=0.65, angle_deg=70, length=520, bow=40, width=3.0, strength=0.9),
         fmt='png', seed=34),
    dict(name='no_holder_border', desc='no holder: the tube enters from the left image border '
         'at a -20 deg tilt; base = border crossing; bright-lumen look', look='bright_lumen',
         W=640, H=480, width_px=15, D_um=350, L_mm=10, bend_deg=150, base_angle_deg=-20,
         holder=dict(kind='none'), entry='left', fmt='png', seed=35),
    dict(name='tapered_pipette', desc='tapered glass pipette (1.3x the tube at its tip, '
         'widening to 2x) with visible walls, base axis 150 deg, -180 deg', look='brightfield',
         W=800, H=600, width_px=24, D_um=400, L_mm=10, bend_deg=-180, base_angle_deg=150,
         holder_len_w=7, holder=dict(kind='pipette', ratio=1.3, wall=0.18, taper=0.12, max_ratio=2.0,
                     contrast=1.4, inner_att=0.6), fmt='png', seed=36),
    dict(name='opaque_mirrored', desc='opaque tube, base on the right pointing left-up '
         '(160 deg), mirrored counter-clockwise curl 260 deg, JPEG folder q75', look='opaque',
         W=640, H=480, width_px=16, D_um=350, L_mm=10, bend_deg=260, base_angle_deg=160,
         sections=[[0.5, 1.2], [0.5, 1.0]], fmt='jpg', quality=75, seed=37),
    dict(name='vignette_gradient', desc='strong vignetting and a left-right illumination '
         'gradient, bright-field, 1280x960, 230 deg, PNG', look='brightfield', W=1280, H=960,
         width_px=28, D_um=450, L_mm=11, bend_deg=230, base_angle_deg=-80,
         illum=dict(gx=0.35, gy=-0.1, vignette=0.45), fmt='png', seed=38),
    dict(name='lowcontrast_flicker', desc='low contrast (x0.3 absorption) with 4 % lamp '
         'flicker, bright-field, 190 deg, MJPG AVI', look='brightfield', contrast=0.3,
         W=640, H=480, width_px=15, D_um=400, L_mm=10, bend_deg=190, base_angle_deg=100,
         flicker=0.04, fmt='avi', quality=90, seed=39),
    dict(name='dust_scratch', desc='many dust specks, out-of-focus dust rings and a straight '
         'scratch, bright-field, -210 deg', look='brightfield', W=800, H=600, width_px=22,
         D_um=400, L_mm=10, bend_deg=-210, base_angle_deg=-175, dust=40,
         scratch=dict(angle_deg=-25, strength=0.10), fmt='png', seed=40),
    dict(name='bf_overcurl_470', desc='bright-field over-curl to 470 deg (1.3 turns), '
         'outward spiral of 2 sections, tip crossing the body and the pipette, MJPG AVI',
         look='brightfield', W=1024, H=768, width_px=16.5, D_um=380, L_mm=12,
         sections=[[0.55, 1.4], [0.45, 0.8]], bend_deg=470, base_angle_deg=-90,
         n_frames=36, ease='smooth', fmt='avi', quality=90, seed=41),
    dict(name='fluor_overcurl_430', desc='fluorescent over-curl to -430 deg (intensities add '
         'where it crosses itself), 12-bit in 16-bit TIFF', look='fluorescent', W=1024,
         H=768, width_px=22, D_um=400, L_mm=12, sections=[[0.5, 1.35], [0.5, 0.85]],
         bend_deg=-430, base_angle_deg=175, n_frames=32, ease='smooth', fmt='tiff12',
         bg=0.05, seed=42, holder=dict(kind='pipette', ratio=1.5, wall=0.15, inner_att=0.5)),
    dict(name='hard_lowsnr_blur_jpeg', desc='hard: low SNR (60 photons), blur sigma 2 px, low '
         'contrast and JPEG q50, bright-field, 240 deg', look='brightfield', contrast=0.5,
         W=640, H=480, width_px=16, D_um=400, L_mm=10, bend_deg=240, base_angle_deg=45,
         noise=dict(photons=60.0, read=0.01), blur=dict(kind='gauss', sigma=2.0), margin=8,
         fmt='jpg', quality=50, seed=43),
    dict(name='wide_pipette_eccentric', desc='thick-walled pipette 2x the tube, eccentric '
         'lumen (thin wall on the convex side), base at the bottom, 200 deg, colour 8-bit TIFF',
         look='bright_lumen', colour='cool', W=800, H=600, width_px=22, D_um=450, L_mm=10,
         ecc=0.15, bend_deg=200, base_angle_deg=75, fmt='tiff8', seed=44,
         holder=dict(kind='pipette', ratio=2.0, wall=0.22, contrast=1.3, inner_att=0.6)),
]


def merged(spec):
    s = json.loads(json.dumps(DEFAULT))
    for k, v in spec.items():
        if k == 'holder':
            h = dict(DEFAULT['holder'])
            h.update(v)
            s['holder'] = h
        else:
            s[k] = v
    return s


# --------------------------------------------------------------------------------------
# geometry (y-up pixel frame: X = col, Y = -row)
# --------------------------------------------------------------------------------------
def arc_xy(P0, phi0, kappa, u):
    """Points at arc length u along a circular arc (or line, kappa=0) from P0, angle phi0."""
    u = np.asarray(u, float)
    x = kappa * u
    sc = np.sinc(x / TWO_PI)                # sin(x/2)/(x/2), exact for kappa -> 0
    return (P0[0] + u * np.cos(phi0 + x / 2) * sc, P0[1] + u * np.sin(phi0 + x / 2) * sc)


class Shape:
    """One frame's tube: elements for drawing and the exact analytic centreline."""

    def __init__(self, base, phi0, lengths, kappas, tail, R, cap, back_len, max_piece):
        self.base = np.asarray(base, float)
        self.phi0 = phi0
        self.R = R
        self.cap = cap
        self.segs = []          # truth pieces (s0, length, P0, phi0, kappa) for s in [0, L]
        self.elements = []      # drawing pieces (also s<0 inside the holder)
        t0 = np.array([math.cos(phi0), math.sin(phi0)])
        P = self.base - back_len * t0
        self._add_draw(P, phi0, 0.0, back_len, -back_len, max_piece)
        P, phi, s = self.base.copy(), phi0, 0.0
        for l, k in zip(lengths, kappas):
            self.segs.append((s, l, P.copy(), phi, k))
            self._add_draw(P, phi, k, l, s, max_piece)
            P = np.array(arc_xy(P, phi, k, l))
            phi += k * l
            s += l
        self.Lb = s
        self.phi_end = phi
        if tail > 1e-9:                                        # straight solid plug
            self.segs.append((s, tail, P.copy(), phi, 0.0))
            self._add_draw(P, phi, 0.0, tail, s, max_piece)
            P = np.array(arc_xy(P, phi, 0.0, tail))
            s += tail
        self.L = s
        self.bend = phi - phi0
        if cap == 'round':
            self._mark_capzone(s - R)
        else:
            self.elements[-1]['ext'] = 1.5                    # flat end: draw a bit past L

    def _mark_capzone(self, sc):
        """The last R of arc is the rounded cap: the tube's half-width there is
        sqrt(R^2 - (s - sc)^2) about the same (still bending) centreline, so the cap's apex is
        the centreline's end point.  Split the element at sc and flag what follows."""
        out = []
        for el in self.elements:
            a, b = el['s0'], el['s0'] + el['length']
            if a < sc - 1e-9 < b - 2e-9:
                l1 = sc - a
                P1 = np.array(arc_xy(el['P0'], el['phi0'], el['kappa'], l1))
                e1 = dict(el, length=l1)
                e2 = dict(el, P0=P1, phi0=el['phi0'] + el['kappa'] * l1, length=b - sc, s0=sc)
                out += [e1, e2]
            else:
                out.append(el)
        for el in out:
            el['capzone'] = el['s0'] >= sc - 1e-9
        out[-1]['ext'] = 1.0        # pixels centred past the apex can still overlap it
        self.elements = out
        self.cap_start = sc

    def _add_draw(self, P, phi, k, l, s0, max_piece):
        n = max(1, int(math.ceil(l / max_piece)), int(math.ceil(abs(k) * l / (math.pi / 4))))
        lj = l / n
        for j in range(n):
            Pj = np.array(arc_xy(P, phi, k, j * lj))
            kind = 'line' if abs(k) < 1e-8 else 'arc'
            self.elements.append(dict(kind=kind, P0=Pj, phi0=phi + k * j * lj, kappa=k,
                                      length=lj, s0=s0 + j * lj, ext=0.0, capzone=False))

    def points(self, s):
        """Exact centreline points (X, Y) at arc positions s in [0, L]."""
        s = np.asarray(s, float)
        X = np.empty_like(s)
        Y = np.empty_like(s)
        starts = np.array([g[0] for g in self.segs])
        idx = np.clip(np.searchsorted(starts, s, side='right') - 1, 0, len(self.segs) - 1)
        for i, (s0, l, P0, ph, k) in enumerate(self.segs):
            m = idx == i
            if m.any():
                X[m], Y[m] = arc_xy(P0, ph, k, s[m] - s0)
        return X, Y

    def truth_polyline(self, step=0.5):
        n = int(math.ceil(self.L / step)) + 1
        s = np.linspace(0.0, self.L, n)
        X, Y = self.points(s)
        return s, X, Y


def bend_schedule(sp):
    n = sp['n_frames']
    hold = sp['hold']
    a0, a1 = math.radians(sp['bend_start_deg']), math.radians(sp['bend_deg'])
    out = []
    for k in range(n):
        t = 0.0 if k < hold else (k - hold) / max(1, n - 1 - hold)
        e = sp['ease']
        if e == 'smooth':
            t = t * t * (3 - 2 * t)
        elif e == 'in':
            t = t * t
        elif e == 'sine':
            t = 0.5 - 0.5 * math.cos(math.pi * t)
        out.append(a0 + (a1 - a0) * t)
    return np.array(out)


def drift_offsets(sp):
    """Per-frame stage offset in (col, row) pixels."""
    n = sp['n_frames']
    d = sp['drift']
    if not d:
        return np.zeros((n, 2))
    a = math.radians(d['angle_deg'])
    k = np.arange(n)
    lin = d['amp'] * k / (n - 1)
    wob = d.get('wobble', 0.0) * np.sin(TWO_PI * 1.3 * k / n)
    dc = lin * math.cos(a) - wob * math.sin(a)
    dr = lin * math.sin(a) + wob * math.cos(a)
    return np.stack([dc, dr], 1)


def build_geometry(sp):
    """Scale, base position and the per-frame shapes of a scene."""
    um = float('%.4g' % (sp['D_um'] / sp['width_px']))
    R = sp['D_um'] / um / 2.0
    L0 = sp['L_mm'] * 1000.0 / um
    tail = sp['plug_w'] * 2 * R
    Lb0 = L0 - tail
    fr = np.array([f for f, _ in sp['sections']], float)
    fr = fr / fr.sum()
    cr = np.array([c for _, c in sp['sections']], float)
    bends = bend_schedule(sp)
    amax = max(abs(bends).max(), 1e-12)
    phi0 = math.radians(sp['base_angle_deg'])
    W, H = sp['W'], sp['H']
    back_len = float(W + H)
    max_piece = max(48.0, 3 * R)

    def shape_at(k, base):
        b = bends[k]
        Lb = Lb0 * (1.0 + sp['elong'] * abs(b) / amax)
        ls = fr * Lb
        kap = b * cr / float((cr * ls).sum())
        return Shape(base, phi0, ls, kap, tail, R, sp['cap'], back_len, max_piece)

    # content rectangle (pixel centres) the tube must stay inside
    c_lo, c_hi, r_lo, r_hi = 0.0, W - 1.0, 0.0, H - 1.0
    if sp['letterbox']:
        r_lo, r_hi = sp['letterbox']['top'], H - 1 - sp['letterbox']['bottom']
    if sp['fieldstop']:
        fs = sp['fieldstop']
        h = fs['r'] / math.sqrt(2) - 4
        c_lo, c_hi = max(c_lo, fs['cx'] - h), min(c_hi, fs['cx'] + h)
        r_lo, r_hi = max(r_lo, fs['cy'] - h), min(r_hi, fs['cy'] + h)
    drift = drift_offsets(sp)
    # extent of every frame relative to the base (col,row offsets), incl. drift
    dcs, drs = [], []
    for k in range(sp['n_frames']):
        sh = shape_at(k, (0.0, 0.0))
        _, X, Y = sh.truth_polyline(1.0)
        dcs.append(X + drift[k, 0])
        drs.append(-Y + drift[k, 1])
    dcs, drs = np.concatenate(dcs), np.concatenate(drs)
    m = sp['margin'] + R
    lo_c, hi_c = c_lo + m - dcs.min(), c_hi - m - dcs.max()
    lo_r, hi_r = r_lo + m - drs.min(), r_hi - m - drs.max()
    tdir = np.array([math.cos(phi0), -math.sin(phi0)])      # base tangent in (col,row)
    if sp['entry']:
        e = sp['entry']
        if e == 'left':
            lo_c = hi_c = c_lo - 0.5
        elif e == 'right':
            lo_c = hi_c = c_hi + 0.5
        elif e == 'top':
            lo_r = hi_r = r_lo - 0.5
        else:
            lo_r = hi_r = r_hi + 0.5
    if lo_c > hi_c + 1e-9 or lo_r > hi_r + 1e-9:
        need = max((dcs.max() - dcs.min() + 2 * m) / (c_hi - c_lo),
                   (drs.max() - drs.min() + 2 * m) / (r_hi - r_lo))
        raise ValueError('%s: tube does not fit (reduce width_px to about %.1f)'
                         % (sp['name'], sp['width_px'] / need * 0.98))
    centre = np.array([(lo_c + hi_c) / 2, (lo_r + hi_r) / 2])
    corner = np.array([lo_c if tdir[0] > 1e-6 else hi_c if tdir[0] < -1e-6 else centre[0],
                       lo_r if tdir[1] > 1e-6 else hi_r if tdir[1] < -1e-6 else centre[1]])
    perp = np.array([-tdir[1], tdir[0]])
    half = np.array([(hi_c - lo_c) / 2, (hi_r - lo_r) / 2])

    def visible(p):
        # length of the holder axis inside the content rectangle, behind the base
        v = 0.0
        for d in np.arange(0, W + H, 1.0):
            c, r = p - tdir * d
            if not (c_lo <= c <= c_hi and r_lo <= r <= r_hi):
                break
            v = d
        return v

    target = sp['holder_len_w'] * 2 * R
    for lam in np.linspace(1.0, 0.0, 51):
        pos = centre + lam * (corner - centre)
        pos = np.clip(pos + sp['perp_shift'] * perp * half, [lo_c, lo_r], [hi_c, hi_r])
        if sp['entry'] or visible(pos) >= target:
            break
    base0 = np.array([pos[0], -pos[1]])                       # y-up
    shapes = []
    for k in range(sp['n_frames']):
        b = base0 + np.array([drift[k, 0], -drift[k, 1]])
        shapes.append(shape_at(k, b))
    # visible holder length (base to the content border, backwards)
    vis = visible(pos)
    if sp['entry']:
        # away from its entry point the tube must stay clear of every border
        for sh in shapes:
            s, X, Y = sh.truth_polyline(1.0)
            far = s > 3 * R
            if (X[far].min() - R < c_lo + 2 or X[far].max() + R > c_hi - 2
                    or -Y[far].max() - R < r_lo + 2 or -Y[far].min() + R > r_hi - 2):
                raise ValueError('%s: the tube leaves the frame away from its entry point'
                                 % sp['name'])
    return dict(um=um, R=R, L0=L0, tail=tail, phi0=phi0, shapes=shapes, base_px=pos,
                drift=drift, bends=bends, content=(c_lo, c_hi, r_lo, r_hi),
                holder_visible_px=vis)


# --------------------------------------------------------------------------------------
# analytic anti-aliased tube fields
# --------------------------------------------------------------------------------------
NANG = 19          # orientations tabulated between 0 and 45 deg


def _box(g, f, width, h):
    """f (sampled on the uniform grid g) convolved with a unit-area box of `width` px."""
    if width < 1e-6:
        return f
    Fc = np.concatenate([[0.0], np.cumsum((f[1:] + f[:-1]) * 0.5 * h)])
    return (np.interp(g + width / 2, g, Fc) - np.interp(g - width / 2, g, Fc)) / width


class Lut2:
    """A radial profile f(n) averaged over a unit pixel, for every edge orientation.

    A unit square pixel seen along a direction at angle t to the pixel's axes projects onto
    that direction as the convolution of two boxes of widths |cos t| and |sin t| (a
    trapezoid), so for a straight edge the tabulated value is the pixel's exact mean of f.
    box=0 gives plain point sampling (for the brute-force reference).
    """

    def __init__(self, func, nmax, box=1.0):
        # grids symmetric about n = 0 (integer multiples of the steps), so that a symmetric
        # profile gives an exactly symmetric table
        h = 0.001
        g = h * np.arange(-int(math.ceil((nmax + 2.0) / h)), int(math.ceil((nmax + 2.0) / h)) + 1)
        self.dq = 0.01
        M = int(math.ceil((nmax + 1.0) / self.dq))
        self.q = self.dq * np.arange(-M, M + 1)
        self.q0 = self.q[0]
        f = func(g)
        rows = []
        for t in np.linspace(0, math.pi / 4, NANG):
            if box <= 0:
                v = f
            else:
                v = _box(g, _box(g, f, box * math.cos(t), h), box * math.sin(t), h)
            rows.append(np.interp(self.q, g, v))
        self.tab = np.array(rows)
        self.tab[:, 0] = 0.0
        self.tab[:, -1] = 0.0

    def __call__(self, n, ang):
        """n: offsets (px); ang: direction of the profile's normal (rad, any)."""
        a = np.abs(np.cos(ang))
        b = np.abs(np.sin(ang))
        t = np.arctan2(np.minimum(a, b), np.maximum(a, b))          # 0..pi/4
        ti = t / (math.pi / 4) * (NANG - 1)
        i0 = np.clip(np.floor(ti).astype(int), 0, NANG - 2)
        ft = ti - i0
        x = (n - self.q0) / self.dq
        j0 = np.clip(np.floor(x).astype(int), 0, self.q.size - 2)
        fx = np.clip(x - j0, 0.0, 1.0)
        T = self.tab
        v0 = T[i0, j0] * (1 - fx) + T[i0, j0 + 1] * fx
        v1 = T[i0 + 1, j0] * (1 - fx) + T[i0 + 1, j0 + 1] * fx
        out = v0 * (1 - ft) + v1 * ft
        return np.where((x < 0) | (x > self.q.size - 1), 0.0, out)


def lut_eval(lut, n, ang=0.0):
    return lut(np.asarray(n, float), np.broadcast_to(ang, np.shape(n)))


class TubeProfiles:
    """Pixel-averaged radial profiles of one tube layer (see Lut2).

    absorb=(c_wall, c_rim, c_lumen), with inner_att, also tabulates the layer's pixel-mean
    transmission 1 - exp(-A(n)) of a hollow stretch and of a solid one (plug, cap), outside
    and inside the holder (absorbance scaled by inner_att), so that transmitted looks
    average the intensity, not the absorbance, over each pixel.
    """

    def __init__(self, R, lumen_frac, ecc_signed, rim_power=8.0, box=1.0, absorb=None,
                 inner_att=1.0):
        self.R = R
        self.box = box
        self.rim_power = rim_power
        self.absorb = absorb
        ri = lumen_frac * R
        e = ecc_signed * R
        nmax = R + 2.0
        self.pad = 1.5

        def solid(n):
            return np.sqrt(np.clip(R * R - n * n, 0, None)) / R

        def lumen(n):
            return np.sqrt(np.clip(ri * ri - (n - e) ** 2, 0, None)) / R

        def rim(n):
            return np.where(np.abs(n) <= R, (np.abs(n) / R) ** rim_power, 0)

        self.cov = Lut2(lambda n: (np.abs(n) <= R).astype(float), nmax, box)
        self.solid = Lut2(solid, nmax, box)
        self.lumen = Lut2(lumen, nmax, box)
        self.rim = Lut2(rim, nmax, box)
        self.step = Lut2(lambda x: (x >= 0).astype(float), 3.0, box)   # for end faces
        self.trans = None
        if absorb is not None:
            cw, cr, cl = absorb

            def A_h(n):
                return cw * (solid(n) - lumen(n)) + cr * rim(n) + cl * lumen(n)

            def A_s(n):
                return cw * solid(n) + cr * rim(n)

            self.trans = dict(
                h1=Lut2(lambda n: 1 - np.exp(-A_h(n)), nmax, box),
                s1=Lut2(lambda n: 1 - np.exp(-A_s(n)), nmax, box),
                ha=Lut2(lambda n: 1 - np.exp(-inner_att * A_h(n)), nmax, box),
                sa=Lut2(lambda n: 1 - np.exp(-inner_att * A_s(n)), nmax, box))


def element_foot(el, X, Y):
    """Foot of (X, Y) on an element's line/arc: arc position u from the element's start
    (signed), lateral offset n (+ to the left of the tangent) and the tangent angle there."""
    P0x, P0y = el['P0']
    ph = el['phi0']
    if el['kind'] == 'line':
        dx, dy = X - P0x, Y - P0y
        u = dx * math.cos(ph) + dy * math.sin(ph)
        n = -dx * math.sin(ph) + dy * math.cos(ph)
        return u, n, np.full(np.shape(u), ph)
    k = el['kappa']
    rho = 1.0 / abs(k)
    Cx, Cy = P0x - math.sin(ph) / k, P0y + math.cos(ph) / k
    vx, vy = X - Cx, Y - Cy
    dist = np.hypot(vx, vy)
    th = np.arctan2(vy, vx)
    if k > 0:
        u = (np.mod(th + math.pi / 2 - ph + math.pi, TWO_PI) - math.pi) / k
        n = rho - dist
    else:
        u = (np.mod(ph - th + math.pi / 2 + math.pi, TWO_PI) - math.pi) / (-k)
        n = dist - rho
    return u, n, ph + k * u


def tube_layers(shape, R, pad, W, H):
    """Every (pixel, n, s, tangent angle, element index) whose pixel centre has its foot
    inside an element (elements never overlap themselves, so one entry = one layer)."""
    idxs, ns, ss, angs, eis = [], [], [], [], []
    rad = R + pad
    for ie, el in enumerate(shape.elements):
        u = np.linspace(0, el['length'] + el['ext'], 9)
        xs, ys = arc_xy(el['P0'], el['phi0'], el['kappa'], u)
        c0 = max(0, int(math.floor(xs.min() - rad - 1)))
        c1 = min(W - 1, int(math.ceil(xs.max() + rad + 1)))
        r0 = max(0, int(math.floor(-ys.max() - rad - 1)))
        r1 = min(H - 1, int(math.ceil(-ys.min() + rad + 1)))
        if c0 > c1 or r0 > r1:
            continue
        cc, rr = np.meshgrid(np.arange(c0, c1 + 1), np.arange(r0, r1 + 1))
        cc = cc.ravel()
        rr = rr.ravel()
        u, n, ang = element_foot(el, cc.astype(float), -rr.astype(float))
        ok = (u >= 0) & (u < el['length'] + el['ext']) & (np.abs(n) < rad)
        if not ok.any():
            continue
        idxs.append(rr[ok] * W + cc[ok])
        ns.append(n[ok])
        ss.append(el['s0'] + u[ok])
        angs.append(ang[ok])
        eis.append(np.full(ok.sum(), ie))
    if not idxs:
        z = np.zeros(0)
        return z.astype(int), z, z, z, z.astype(int)
    return (np.concatenate(idxs), np.concatenate(ns), np.concatenate(ss), np.concatenate(angs),
            np.concatenate(eis))


CAP_SS = 8     # super-sampling of the rounded cap's pixels


def cap_samples(shape, prof, idx, eis, W):
    """Point samples (CAP_SS x CAP_SS per pixel) of the rounded cap's pixels.

    Returns, per pixel entry, the sample means of: coverage, solid path/(2R), rim term, and
    the transmission deficit 1 - exp(-A) of a solid stretch (if the look has one)."""
    R = prof.R
    sc = shape.cap_start
    offs = (np.arange(CAP_SS) + 0.5) / CAP_SS - 0.5
    ox, oy = np.meshgrid(offs, offs)
    ox, oy = ox.ravel(), oy.ravel()
    col = (idx % W).astype(float)
    row = (idx // W).astype(float)
    out = dict(cov=np.zeros(idx.size), solid=np.zeros(idx.size), rim=np.zeros(idx.size),
               D=np.zeros(idx.size), s=np.zeros(idx.size))
    for ie in np.unique(eis):
        m = eis == ie
        el = shape.elements[ie]
        X = col[m][:, None] + ox[None, :]
        Y = -(row[m][:, None] + oy[None, :])
        u, n, _ = element_foot(el, X, Y)
        s = el['s0'] + u
        a = np.maximum(s - sc, 0.0)
        Rs2 = np.clip(R * R - a * a, 0.0, None)
        inside = (s <= shape.L) & (n * n <= Rs2)
        solid = np.where(inside, np.sqrt(np.clip(Rs2 - n * n, 0, None)) / R, 0.0)
        rim = np.where(inside, ((a * a + n * n) / (R * R)) ** (prof.rim_power / 2), 0.0)
        out['cov'][m] = inside.mean(1)
        out['solid'][m] = solid.mean(1)
        out['rim'][m] = rim.mean(1)
        out['s'][m] = np.where(inside, s, 0).sum(1) / np.maximum(inside.sum(1), 1)
        if prof.absorb is not None:
            cw, cr, _ = prof.absorb
            out['D'][m] = (1.0 - np.exp(-(cw * solid + cr * rim))).mean(1)
    return out


def smooth_step(x):
    """Box-prefiltered unit step (1 for x > 0.5, 0 for x < -0.5)."""
    return np.clip(x + 0.5, 0.0, 1.0)


def tube_fields(shape, prof, sp, W, H, inner_att, opaque_alpha=0.9):
    R = prof.R
    idx, n, s, ang, eis = tube_layers(shape, R, prof.pad, W, H)
    L = shape.L
    capz = np.array([shape.elements[i]['capzone'] for i in eis], bool) if eis.size else \
        np.zeros(0, bool)
    is_last = eis == len(shape.elements) - 1
    beta = smooth_step(s)                                       # 0 inside the holder
    w = inner_att + (1.0 - inner_att) * beta
    if shape.cap == 'flat':
        # the end face: a straight edge across the tube at s = L
        w = w * np.where(is_last, prof.step(np.clip(L - s, -2.5, 2.5), ang), 1.0)
    cov = prof.cov(n, ang) * w
    solid = prof.solid(n, ang) * w
    # the lumen ends inside the solid end: before the flat end wall, the plug, or the
    # rounded cap (its 1-px ramp done before the cap's super-sampled zone)
    lum_end = L - max(shape_tail(shape, sp),
                      0.3 * R if shape.cap == 'flat' else R + max(0.1 * R, 0.6))
    ml = np.where(capz, 0.0, smooth_step(lum_end - s))
    lum = prof.lumen(n, ang) * w * ml
    rim = prof.rim(n, ang) * w
    D = None
    if prof.trans is not None:
        T = prof.trans
        D = (beta * (ml * T['h1'](n, ang) + (1 - ml) * T['s1'](n, ang))
             + (1 - beta) * (ml * T['ha'](n, ang) + (1 - ml) * T['sa'](n, ang)))
        if shape.cap == 'flat':
            D = D * np.where(is_last, prof.step(np.clip(L - s, -2.5, 2.5), ang), 1.0)
    if capz.any():                                              # rounded cap: super-sampled
        cs = cap_samples(shape, prof, idx[capz], eis[capz], W)
        cov[capz] = cs['cov']
        solid[capz] = cs['solid']
        rim[capz] = cs['rim']
        lum[capz] = 0.0
        s = s.copy()
        s[capz] = np.where(cs['cov'] > 0, cs['s'], s[capz])
        if D is not None:
            D[capz] = cs['D']
    glow_len = 0.5 * R
    tipm = np.clip((s - (L - glow_len)) / glow_len, 0, 1)
    N = W * H

    def acc(v):
        return np.bincount(idx, weights=v, minlength=N).reshape(H, W)

    F = dict(cov=acc(cov), solid=acc(solid), lumen=acc(lum), rim=acc(rim),
             tip=acc(solid * tipm),
             logopq=acc(np.log(np.clip(1.0 - opaque_alpha * cov, 1e-6, None))))
    if D is not None:
        F['logT'] = acc(np.log(np.clip(1.0 - D, 1e-9, None)))
    F['wall'] = F['solid'] - F['lumen']
    return F


def shape_tail(shape, sp):
    return max(sp['plug_w'] * 2 * shape.R, 0.0)


def holder_fields(sp, base, phi0, R, W, H, ss=4):
    """Super-sampled glass pipette behind the base (flat open end at s=0)."""
    h = sp['holder']
    ratio = h['ratio']
    taper = h.get('taper', 0.0) or 0.0
    mx = h.get('max_ratio') or ratio
    Rp0, Rpm = ratio * R, mx * R
    wall = min(h['wall'], 1.0 - 1.04 / ratio)
    c, s_ = math.cos(phi0), math.sin(phi0)
    cc, rr = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    dx, dy = cc - base[0], -rr - base[1]
    ub = -(dx * c + dy * s_)             # distance behind the base
    nb = -dx * s_ + dy * c
    cand = (ub >= -1.5) & (np.abs(nb) <= Rpm + 1.5)
    ci, ri = cc[cand], rr[cand]
    acc = {k: np.zeros(ci.size) for k in ('cov', 'wall', 'rim', 'fluid', 'T')}
    hc = h.get('contrast', 1.0)
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    for ox in offs:
        for oy in offs:
            X, Y = ci + ox, -(ri + oy)
            ddx, ddy = X - base[0], Y - base[1]
            u = -(ddx * c + ddy * s_)
            n = -ddx * s_ + ddy * c
            Rp = np.minimum(Rp0 + taper * np.maximum(u, 0), Rpm)
            rp = Rp * (1 - wall)
            inside = (u >= 0) & (np.abs(n) <= Rp)
            wp = (np.sqrt(np.clip(Rp ** 2 - n ** 2, 0, None))
                  - np.sqrt(np.clip(rp ** 2 - n ** 2, 0, None))) / Rp
            acc['cov'] += inside
            acc['wall'] += np.where(inside, wp, 0)
            acc['rim'] += np.where(inside, (np.abs(n) / Rp) ** 10, 0)
            acc['fluid'] += inside & (np.abs(n) < rp)
            acc['T'] += np.exp(-hc * np.where(inside, 0.3 * wp + 1.2 * (np.abs(n) / Rp) ** 10, 0))
    out = {}
    for k, v in acc.items():
        img = np.ones((H, W)) if k == 'T' else np.zeros((H, W))
        img[cand] = v / (ss * ss)
        out[k] = img
    out['logT'] = np.log(out.pop('T'))
    return out


# --------------------------------------------------------------------------------------
# looks and nuisances
# --------------------------------------------------------------------------------------
TINTS = dict(
    halogen=dict(bg=(1.0, 0.90, 0.66), absorb=(0.9, 1.0, 1.25)),
    cool=dict(bg=(0.86, 0.95, 1.0), absorb=(1.1, 1.0, 0.9)),
    green=dict(em=(0.18, 1.0, 0.32), bg=(0.3, 1.0, 0.5)),
)


def illumination(sp, W, H):
    il = sp['illum']
    cc, rr = np.meshgrid(np.linspace(-1, 1, W), np.linspace(-1, 1, H))
    B = 1.0 + il.get('gx', 0.0) * cc + il.get('gy', 0.0) * rr
    v = il.get('vignette', 0.0)
    if v:
        r2 = (cc * W / max(W, H)) ** 2 + (rr * H / max(W, H)) ** 2
        B = B * (1.0 - v * r2 / 1.0)
    return B


def static_clutter(sp, geo, W, H, rng):
    """Dust specks, dust rings, a fibre and a scratch: absorbance map (static, not drifting)."""
    A = np.zeros((H, W))
    cc, rr = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    for _ in range(sp['dust']):
        x, y = rng.uniform(0, W), rng.uniform(0, H)
        if rng.random() < 0.75:
            sg = rng.uniform(0.7, 2.5)
            a = rng.uniform(0.15, 0.6)
            r0 = int(4 * sg + 2)
            c0, c1 = int(max(0, x - r0)), int(min(W, x + r0 + 1))
            r0_, r1 = int(max(0, y - r0)), int(min(H, y + r0 + 1))
            sub = (cc[r0_:r1, c0:c1] - x) ** 2 + (rr[r0_:r1, c0:c1] - y) ** 2
            A[r0_:r1, c0:c1] += a * np.exp(-sub / (2 * sg * sg))
        else:                                               # out-of-focus dust: faint ring
            rad = rng.uniform(8, 22)
            a = rng.uniform(0.03, 0.08)
            r0 = int(rad + 6)
            c0, c1 = int(max(0, x - r0)), int(min(W, x + r0 + 1))
            r0_, r1 = int(max(0, y - r0)), int(min(H, y + r0 + 1))
            d = np.hypot(cc[r0_:r1, c0:c1] - x, rr[r0_:r1, c0:c1] - y)
            A[r0_:r1, c0:c1] += a * (np.exp(-((d - rad) / 1.5) ** 2) + 0.4 * (d < rad))
    fb = sp['fibre']
    if fb:
        sh = geo['shapes'][-1]
        X, Y = sh.points(np.array([fb['at_s'] * sh.L]))
        p = np.array([X[0], -Y[0]])
        a = math.radians(fb['angle_deg'])
        d = np.array([math.cos(a), -math.sin(a)])
        nrm = np.array([-d[1], d[0]])
        t = np.linspace(-0.5, 0.5, int(fb['length'] * 4))
        pts = (p[None] + t[:, None] * fb['length'] * d[None]
               + (1 - 4 * t[:, None] ** 2) * fb['bow'] * nrm[None] - fb['bow'] * 0.7 * nrm)
        from scipy.spatial import cKDTree
        tree = cKDTree(pts)
        dist, _ = tree.query(np.stack([cc.ravel(), rr.ravel()], 1),
                             distance_upper_bound=4 * fb['width'])
        dist = dist.reshape(H, W)
        sg = fb['width'] / 2.355
        A += fb['strength'] * np.where(np.isfinite(dist), np.exp(-dist ** 2 / (2 * sg * sg)), 0)
    sc = sp['scratch']
    if sc:
        a = math.radians(sc['angle_deg'])
        x0, y0 = rng.uniform(0.3, 0.7) * W, rng.uniform(0.3, 0.7) * H
        dist = np.abs(-(cc - x0) * math.sin(a) - (rr - y0) * math.cos(a))
        A -= sc['strength'] * np.exp(-dist ** 2 / (2 * 0.6 ** 2))   # a bright thin line
    return A


def psf(img, blur):
    if not blur:
        return img
    if blur['kind'] == 'gauss':
        if blur['sigma'] <= 0:
            return img
        return cv2.GaussianBlur(img, (0, 0), blur['sigma'], borderType=cv2.BORDER_REFLECT)
    r = blur['radius']
    ss = 8
    n = int(math.ceil(r)) + 1
    # integrate the disc over each pixel (8x8 sub-samples)
    size = 2 * n + 1
    kern = np.zeros((size, size))
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    for ox in offs:
        for oy in offs:
            xx, yy = np.meshgrid(np.arange(-n, n + 1) + ox, np.arange(-n, n + 1) + oy)
            kern += (xx ** 2 + yy ** 2 <= r * r)
    kern /= kern.sum()
    return cv2.filter2D(img, -1, kern, borderType=cv2.BORDER_REFLECT)


# absorbance of a tube layer: A = c_wall*wall + c_rim*rim + c_lumen*lumen (x contrast)
ABSORB = dict(brightfield=(0.55, 1.1, 0.05), bright_lumen=(0.25, 1.3, -0.45))


def make_profiles(sp, R, ecc_signed=0.0, box=1.0):
    ab = ABSORB.get(sp['look'])
    if ab is not None:
        ab = tuple(sp['contrast'] * c for c in ab)
    att = sp['holder'].get('inner_att', 0.6) if sp['holder']['kind'] != 'none' else 1.0
    return TubeProfiles(R, sp['lumen_frac'], ecc_signed, box=box, absorb=ab, inner_att=att)


def compose(sp, F, Hf, B, clutter, gain, prof_info):
    """Clean intensity image (float, ~0..1), grey (H,W) or RGB (H,W,3)."""
    look = sp['look']
    k = sp['contrast']
    hc = sp['holder'].get('contrast', 1.0)
    col = TINTS.get(sp['colour']) if sp['colour'] else None
    if look in ('brightfield', 'bright_lumen', 'opaque'):
        if look in ABSORB:
            A = -F['logT']
        else:
            A = -F['logopq']
        Ah = -Hf['logT'] if Hf else 0.0
        A_all = A + Ah + clutter
        Bg = sp['bg'] * B * gain
        if col:
            ab = np.array(col.get('absorb', (1, 1, 1)))
            bgc = np.array(col.get('bg', (1, 1, 1)))
            return Bg[..., None] * bgc * np.exp(-A_all[..., None] * ab)
        return Bg * np.exp(-A_all)
    if look in ('phase', 'dic'):
        opl = k * F['solid'] + (0.6 * hc * Hf['wall'] if Hf else 0.0)
        if look == 'phase':
            sig = prof_info['halo_sigma']
            low = cv2.GaussianBlur(opl, (0, 0), sig, borderType=cv2.BORDER_REFLECT)
            I = sp['bg'] * B * gain * np.clip(1.0 - 0.9 * (opl - low) - 0.08 * opl, 0.03, None)
            return I * np.exp(-clutter)
        g = cv2.GaussianBlur(opl, (0, 0), 1.0, borderType=cv2.BORDER_REFLECT)
        gy, gx = np.gradient(g)                    # d/drow, d/dcol
        a = math.radians(sp['dic_shear_deg'])
        d = gx * math.cos(a) - gy * math.sin(a)    # derivative along the shear (y-up angle)
        I = sp['bg'] * B * gain * (1.0 + prof_info['dic_gain'] * d - 0.05 * opl)
        return np.clip(I, 0.01, None) * np.exp(-clutter)
    # fluorescent
    E = k * (0.55 * F['wall'] + 0.12 * F['lumen'] + sp.get('end_glow', 0.0) * F['tip'])
    Eh = (0.05 * Hf['wall'] + 0.02 * Hf['fluid']) * hc if Hf else 0.0
    Em = (E + Eh + 0.5 * np.clip(clutter, 0, None)) * B * gain
    if col:
        em = np.array(col['em'])
        bgc = np.array(col['bg'])
        return sp['bg'] * bgc * B[..., None] + Em[..., None] * em
    return sp['bg'] * B + Em


def add_noise(I, noise, rng):
    ph = noise['photons']
    out = rng.poisson(np.clip(I, 0, None) * ph) / ph if ph else I.copy()
    return out + rng.normal(0.0, noise['read'], I.shape)


def frame_masks(sp, W, H):
    m = np.ones((H, W))
    if sp['fieldstop']:
        fs = sp['fieldstop']
        cc, rr = np.meshgrid(np.arange(W), np.arange(H))
        d = np.hypot(cc - fs['cx'], rr - fs['cy'])
        m = np.clip((fs['r'] - d) / 2.0 + 0.5, 0, 1)
    return m


# --------------------------------------------------------------------------------------
# writers
# --------------------------------------------------------------------------------------
def quantise(I, fmt):
    if fmt == 'tiff16':
        return np.clip(np.round(I * 65535), 0, 65535).astype(np.uint16)
    if fmt == 'tiff12':
        return np.clip(np.round(100 + I * 3995), 0, 4095).astype(np.uint16)
    return np.clip(np.round(I * 255), 0, 255).astype(np.uint8)


class Writer:
    def __init__(self, sp, folder):
        self.sp = sp
        self.folder = folder
        self.fmt = sp['fmt']
        self.frames = []
        self.vw = None
        W, H = sp['W'], sp['H']
        if self.fmt == 'avi':
            self.input = 'video.avi'
            self.vw = cv2.VideoWriter(os.path.join(folder, self.input), cv2.CAP_OPENCV_MJPEG,
                                      cv2.VideoWriter_fourcc(*'MJPG'), sp['fps'], (W, H), True)
            self.vw.set(cv2.VIDEOWRITER_PROP_QUALITY, sp['quality'])
        elif self.fmt == 'mp4':
            self.input = 'video.mp4'
            self.vw = cv2.VideoWriter(os.path.join(folder, self.input), cv2.CAP_FFMPEG,
                                      cv2.VideoWriter_fourcc(*'mp4v'), sp['fps'], (W, H), True)
        elif self.fmt in ('png', 'jpg'):
            self.input = 'frames'
            os.makedirs(os.path.join(folder, 'frames'))
        else:
            self.input = 'stack.tif'
        if self.vw is not None and not self.vw.isOpened():
            raise RuntimeError('cannot open video writer for ' + self.fmt)

    def add(self, k, q):
        bgr = q[..., ::-1] if q.ndim == 3 else q
        if self.vw is not None:
            if bgr.ndim == 2:
                bgr = cv2.cvtColor(bgr, cv2.COLOR_GRAY2BGR)
            self.vw.write(np.ascontiguousarray(bgr))
        elif self.fmt == 'png':
            cv2.imwrite(os.path.join(self.folder, 'frames', 'frame_%04d.png' % k), bgr)
        elif self.fmt == 'jpg':
            cv2.imwrite(os.path.join(self.folder, 'frames', 'frame_%04d.jpg' % k), bgr,
                        [cv2.IMWRITE_JPEG_QUALITY, self.sp['quality']])
        else:
            self.frames.append(q)

    def close(self):
        if self.vw is not None:
            self.vw.release()
        elif self.frames:
            st = np.stack(self.frames)
            tifffile.imwrite(os.path.join(self.folder, self.input), st,
                             photometric='rgb' if st.ndim == 4 else 'minisblack')


# --------------------------------------------------------------------------------------
# scene rendering
# --------------------------------------------------------------------------------------
def look_info(sp, R):
    info = dict(halo_sigma=max(2.0, 0.7 * R))
    if sp['look'] == 'dic':
        # gain so that a tube across the shear gives a relief of about +-0.35
        prof = TubeProfiles(R, sp['lumen_frac'], 0.0)
        x = np.arange(-3 * R - 10, 3 * R + 10, 1.0)
        p = lut_eval(prof.solid, x)
        g = cv2.GaussianBlur(p[None, :], (0, 0), 1.0)[0]
        info['dic_gain'] = 0.35 / (np.abs(np.gradient(g)).max() * sp['contrast'])
    return info


def render_frame_clean(sp, geo, k, prof, Hf, B, clutter, gain, info):
    W, H = sp['W'], sp['H']
    sh = geo['shapes'][k]
    inner_att = sp['holder'].get('inner_att', 0.6) if sp['holder']['kind'] != 'none' else 1.0
    F = tube_fields(sh, prof, sp, W, H, inner_att, opaque_alpha=0.88)
    return compose(sp, F, Hf, B, clutter, gain, info), F


def render_scene(spec, out_root=SCENE_ROOT, verbose=True):
    t0 = time.time()
    sp = merged(spec)
    name = sp['name']
    folder = os.path.join(out_root, name)
    if os.path.exists(folder):
        shutil.rmtree(folder)
    os.makedirs(folder)
    geo = build_geometry(sp)
    W, H = sp['W'], sp['H']
    R = geo['R']
    um = geo['um']
    rng = np.random.default_rng(sp['seed'])
    bsign = math.copysign(1.0, sp['bend_deg'] if sp['bend_deg'] != 0 else sp['bend_start_deg'])
    # thick wall on the concave side, so the lumen is shifted towards the convex side
    prof = make_profiles(sp, R, -sp['ecc'] * bsign)
    info = look_info(sp, R)
    B = illumination(sp, W, H)
    clutter = static_clutter(sp, geo, W, H, rng)
    mask = frame_masks(sp, W, H)
    gains = 1.0 + sp['flicker'] * rng.standard_normal(sp['n_frames'])
    has_holder = sp['holder']['kind'] != 'none'
    Hf_static = None
    if has_holder and not sp['drift']:
        sh = geo['shapes'][0]
        Hf_static = holder_fields(sp, sh.base, sh.phi0, R, W, H)
    wr = Writer(sp, folder)
    rows_t, rows_c = [], []
    for k in range(sp['n_frames']):
        sh = geo['shapes'][k]
        Hf = Hf_static if Hf_static is not None else (
            holder_fields(sp, sh.base, sh.phi0, R, W, H) if has_holder else None)
        I, _ = render_frame_clean(sp, geo, k, prof, Hf, B, clutter, gains[k], info)
        I = psf(I, sp['blur'])
        if I.ndim == 3:
            I = I * mask[..., None]
        else:
            I = I * mask
        frng = np.random.default_rng([sp['seed'], k])
        I = add_noise(I, sp['noise'], frng)
        if sp['letterbox']:
            lb = sp['letterbox']
            I[:lb['top']] = 0.0
            I[H - lb['bottom']:] = 0.0
        wr.add(k, quantise(I, sp['fmt']))
        # truth
        s, X, Y = sh.truth_polyline(0.5)
        t = k / sp['fps']
        rows_t.append((k, t, math.degrees(sh.bend), X[-1] * um, Y[-1] * um, X[0] * um,
                       Y[0] * um, sh.L * um, 'ok'))
        for si, xi, yi in zip(s, X, Y):
            rows_c.append((k, si * um, xi * um, yi * um))
    wr.close()
    with open(os.path.join(folder, 'truth_tracks.csv'), 'w') as f:
        f.write('frame,time_s,bend_angle_deg,tip_x_um,tip_y_um,base_x_um,base_y_um,'
                'length_um,status\n')
        for r in rows_t:
            f.write('%d,%.6f,%.6f,%.5f,%.5f,%.5f,%.5f,%.5f,%s\n' % r)
    with open(os.path.join(folder, 'truth_centrelines.csv'), 'w') as f:
        f.write('frame,s_um,x_um,y_um\n')
        for r in rows_c:
            f.write('%d,%.5f,%.5f,%.5f\n' % r)
    sh0 = geo['shapes'][0]
    meta = dict(
        name=name, description=sp['desc'], input=wr.input, um_per_px=um,
        fps=sp['fps'], n_frames=sp['n_frames'], width=W, height=H,
        format=sp['fmt'] + ('' if sp['fmt'] not in ('jpg', 'avi') else ' q%d' % sp['quality']),
        colour=bool(sp['colour']),
        derived=dict(tube_width_px=2 * R, tube_length_px_rest=geo['L0'],
                     tube_length_px_max=max(s.L for s in geo['shapes']),
                     tail_straight_px=geo['tail'], base_px_frame0=[sh0.base[0], -sh0.base[1]],
                     base_angle_deg=sp['base_angle_deg'],
                     holder_visible_px=geo['holder_visible_px'] if has_holder else 0.0,
                     bend_deg_first=math.degrees(geo['bends'][0]),
                     bend_deg_last=math.degrees(geo['bends'][-1]),
                     content_rect_cols_rows=list(geo['content'])),
        conventions=dict(
            pixel_centre='pixel (col,row) has its centre at (col,row); top-left centre (0,0)',
            coords='x_um = col*um_per_px, y_um = -row*um_per_px (y up)',
            bend='unwrapped CCW rotation of the tip tangent relative to the base tangent, '
                 'tangents base->tip, degrees (clockwise negative)',
            base='point where the tube leaves the holder (pipette end face); with no holder '
                 'the point where the centreline crosses the image border (outer pixel edge)',
            tip='end of the centreline at the tube\'s physical end (apex of the round cap '
                'or the flat end face); length_um = arc length base->tip',
            centreline='truth_centrelines.csv: exact analytic points every <=0.5 px'),
        settings=sp,
        render_seconds=round(time.time() - t0, 2),
    )
    with open(os.path.join(folder, 'scene.json'), 'w') as f:
        json.dump(meta, f, indent=1)
    if verbose:
        print('%-26s %4dx%-4d w=%5.1fpx L=%6.0fpx bend %7.1f..%7.1f  %-6s %5.1fs'
              % (name, W, H, 2 * R, geo['L0'], math.degrees(geo['bends'][0]),
                 math.degrees(geo['bends'][-1]), sp['fmt'], time.time() - t0), flush=True)
    return name


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--only', nargs='*')
    ap.add_argument('--list', action='store_true')
    ap.add_argument('-j', type=int, default=2)
    ap.add_argument('--out', default=SCENE_ROOT)
    a = ap.parse_args(argv)
    specs = [s for s in SCENES if not a.only or s['name'] in a.only]
    if a.list:
        for s in specs:
            print('%-26s %s' % (s['name'], s['desc']))
        return
    t0 = time.time()
    os.makedirs(a.out, exist_ok=True)
    if not a.only:
        for d in os.listdir(a.out):
            if d not in {s['name'] for s in SCENES}:
                shutil.rmtree(os.path.join(a.out, d))
    if a.j > 1:
        with ProcessPoolExecutor(a.j) as ex:
            list(ex.map(render_scene, specs, [a.out] * len(specs)))
    else:
        for s in specs:
            render_scene(s, a.out)
    print('rendered %d scenes in %.1f s' % (len(specs), time.time() - t0))


if __name__ == '__main__':
    main()

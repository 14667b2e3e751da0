#!/usr/bin/env python
"""alien6: render the synthetic evaluation scenes for a bending-microtube tracker.

    python render.py [-j 2] [--only NAME ...] [--list] [--check]

Every scene's seed comes from its name (sha256), so rendering is deterministic.
Scenes go to ./scenes/<name>/ (frames, scene.json, truth_tracks.csv, truth_centrelines.csv).
--check runs the convention self-checks and the per-scene truth/file checks (after rendering).
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
from concurrent.futures import ProcessPoolExecutor

import cv2
import numpy as np
import tifffile
from PIL import Image

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = os.path.join(HERE, 'scenes')

# --------------------------------------------------------------------------------------------
# sampling pattern: 16 samples per pixel on a rank-1 lattice (every sample has its own row and
# column offset; the offset sets are symmetric about the pixel centre)
S2 = 16
_k = np.arange(S2)
OX = (_k + 0.5) / S2 - 0.5
OY = (((_k * 5) % S2) + 0.5) / S2 - 0.5


def seed_of(name, extra=0):
    return (int.from_bytes(hashlib.sha256(name.encode()).digest()[:4], 'little') + extra) % (2**32)


def tvec(th):
    return np.array([math.cos(th), math.sin(th)])


def nvec(th):
    return np.array([-math.sin(th), math.cos(th)])


# --------------------------------------------------------------------------------------------
# geometry: a chain of exact circular arcs in the math frame (X = col, Y = -row), px units
class Chain:
    def __init__(self, base, th0, lens, kaps, back_len=6000.0):
        self.base = np.asarray(base, float)
        self.th0 = th0
        self.lens = list(lens)
        self.kaps = list(kaps)
        self.L = float(sum(lens))
        self.bend = float(sum(k * l for k, l in zip(kaps, lens)))
        arcs = [(self.base - back_len * tvec(th0), th0, 0.0, back_len, -back_len)]
        P, th, s = self.base.copy(), th0, 0.0
        for l, k in zip(lens, kaps):
            nsub = int(max(1, math.ceil(abs(k) * l / (math.pi / 6)), math.ceil(l / 120.0)))
            for _ in range(nsub):
                ll = l / nsub
                arcs.append((P.copy(), th, k, ll, s))
                P = self._pt(P, th, k, ll)
                th += k * ll
                s += ll
        self.arcs = arcs
        self.tip = P
        self.th_tip = th
        self.s0 = np.array([a[4] for a in arcs])

    @staticmethod
    def _pt(P, th, k, sig):
        sig = np.asarray(sig, float)
        if abs(k) < 1e-12:
            return np.stack([P[0] + sig * math.cos(th), P[1] + sig * math.sin(th)], -1)
        return np.stack([P[0] + (np.sin(th + k * sig) - math.sin(th)) / k,
                         P[1] + (-np.cos(th + k * sig) + math.cos(th)) / k], -1)

    def points(self, s):
        s = np.asarray(s, float)
        idx = np.clip(np.searchsorted(self.s0, s, side='right') - 1, 0, len(self.arcs) - 1)
        out = np.zeros((len(s), 2))
        th = np.zeros(len(s))
        for i in np.unique(idx):
            m = idx == i
            P, t0, k, ll, s0 = self.arcs[i]
            sig = s[m] - s0
            out[m] = self._pt(P, t0, k, sig)
            th[m] = t0 + k * sig
        return out, th

    def kappa_at(self, s):
        idx = np.clip(np.searchsorted(self.s0, np.asarray(s, float), side='right') - 1, 0,
                      len(self.arcs) - 1)
        return np.array([self.arcs[i][2] for i in np.atleast_1d(idx)])

    def foot(self, i, X, Y):
        """foot point on arc i of samples (X,Y): global s, signed d (left +), heading, valid."""
        P, th, k, ll, s0 = self.arcs[i]
        if abs(k) < 1e-12:
            dx, dy = X - P[0], Y - P[1]
            sig = dx * math.cos(th) + dy * math.sin(th)
            d = -dx * math.sin(th) + dy * math.cos(th)
            thF = np.full(X.shape, th)
        else:
            C = P + nvec(th) / k
            Vx, Vy = X - C[0], Y - C[1]
            rho = np.hypot(Vx, Vy)
            phi = np.arctan2(Vy, Vx)
            Rk = 1.0 / abs(k)
            if k > 0:
                thF = phi + math.pi / 2
                dth = np.mod(thF - th, 2 * math.pi)
            else:
                thF = phi - math.pi / 2
                dth = np.mod(th - thF, 2 * math.pi)
            sig = dth * Rk
            d = math.copysign(1.0, k) * (Rk - rho)
            thF = th + k * sig
        valid = (sig >= 0) & (sig < ll)
        return s0 + sig, d, thF, valid


# --------------------------------------------------------------------------------------------
# scene definitions
BASE = dict(
    W=640, H=480, um=20.0, od_um=350.0, id_frac=0.6, ecc=0.15, L_um=9000.0, elong=0.0,
    fracs=[1.0], ratios=[1.0], rest_ratios=None, bend=150.0, rest=0.0,
    heading=0.0, place='auto', base_px=None, bias=(0.0, 0.0), cap='round',
    holder='pipette', pip_ro=1.55, pip_ri=1.06, glass_a=0.04, glass_dn=0.09, glass_glow=0.0,
    clamp_hw=2.5, sleeve=None, glue=None,
    look='bf', a_w=0.22, a_l=0.0, dn_w=0.08, dn_l=-0.33, NA=0.13, rim_k=1.0, NA_df=0.30,
    tint=None, light=None, obl_dir=30.0, obl_k=0.8, obl_c=0.25, polar=None, spec=None,
    twist=None, psf=0.9, psf_t=None, n=24, fps=10.0, p='ease', p_args={}, blur=None,
    shake=None, gain_t=None, vig=0.08, grad=(0.05, 30.0), shadow=None, grid=None,
    meniscus=None, letterbox=None, level=0.78, rn=0.006, shot=0.00012, fmt='avi:MJPG',
    description='', tests='',
)


def S(name, **kw):
    d = dict(BASE)
    d.update(kw)
    d['name'] = name
    return d


def width_um(w_px, od):
    return od / w_px


SCENE_LIST = [
    # ---- ordinary but different (sanity baseline)
    S('bf_baseline_640_mjpg', W=640, H=480, um=350 / 16, L_um=9000, bend=170,
      description='brightfield, thin glass pipette from the left, one section, 0 -> 170 deg, '
                  'tube 16 px wide, 640x480, MJPG AVI',
      tests='baseline: ordinary setup'),
    S('bf_portrait_768x1024_png', W=768, H=1024, um=400 / 28, od_um=400, L_um=10000,
      heading=90.0, fracs=[0.5, 0.5], ratios=[1.0, 1.6], bend=-200, n=20, fmt='png',
      description='camera rotated 90 deg (portrait 768x1024), pipette from the bottom, '
                  '2 sections (1:1.6), clockwise to -200 deg, 28 px wide, 8-bit PNG folder',
      tests='portrait frame; base at the bottom; clockwise'),
    S('bf_large_2048_tif8', W=2048, H=1536, um=450 / 56, od_um=450, L_um=11000,
      heading=180.0, fracs=[0.3, 0.3, 0.4], ratios=[1.0, 0.5, 1.5], bend=230, n=16,
      psf=1.4, fmt='tif8',
      description='2048x1536, tube 56 px wide, 11 mm = 1370 px, pipette from the right, '
                  '3 sections (1:0.5:1.5), 0 -> 230 deg, 8-bit multi-page TIFF',
      tests='large frame and wide tube'),
    S('bf_border_small_320_ffv1', W=320, H=240, um=300 / 7, od_um=300, L_um=8500,
      holder=None, place='border:bottom', heading=82.0, bend=160, fmt='avi:FFV1', psf=0.8,
      description='320x240, no holder: tube 7 px wide enters across the bottom border '
                  'heading 82 deg, 0 -> 160 deg, FFV1 AVI',
      tests='small frame, base on the border'),
    # ---- looks
    S('darkfield_rims_mkv', W=800, H=600, um=350 / 20, L_um=9500, heading=10.0, bend=190,
      look='df', n=20, fmt='mkv:FFV1',
      description='dark-field: black background, only the tube edges (and lumen interfaces, '
                  'pipette glass edges) scatter light: two bright rims; pipette from the left '
                  'at 10 deg; 0 -> 190 deg; MKV (FFV1)',
      tests='inverted look: bright thin rims on black, interior dark'),
    S('oblique_saturated_avi', W=640, H=480, um=350 / 15, L_um=9000, heading=270.0,
      bend=160, look='obl', obl_dir=20.0, obl_k=1.0, level=0.68, n=20, dn_l=0.0,
      description='oblique (side) illumination from 20 deg (water-filled lumen): one edge of the tube bright and '
                  'clipped at white, the other dark; pipette from the top; 0 -> 160 deg; MJPG',
      tests='one-sided relief; saturated edge; edge sign flips as the tube turns'),
    S('liquid_lumen_thinwall_png', W=800, H=600, um=500 / 40, od_um=500, L_um=8000,
      id_frac=0.82, ecc=0.5, a_w=1.1, a_l=0.0, dn_l=0.0, NA=0.25, rim_k=0.5, bend=150,
      n=20, fmt='png',
      description='water-filled wide lumen (ID 0.82 OD, offset half the wall): the lumen is '
                  'bright, the wall dark, weak rims: the tube looks like two dark lines of '
                  'unequal width; pipette from the left; 0 -> 150 deg; 40 px wide; PNG',
      tests='hollow look (bright interior); eccentric walls'),
    S('hand_shadow_moving', W=640, H=480, um=350 / 15, L_um=9000, bend=-180,
      shadow=dict(depth=0.6, soft=35.0, r=700.0, c0=(-900, 100), c1=(-150, 260)),
      fmt='avi:FFV1',
      description='the soft shadow of a hand sweeps over the field from the left: the tube '
                  'and background darken to 40 % behind a moving curved edge; pipette from '
                  'the left; 0 -> -180 deg; FFV1',
      tests='moving large-scale shading, tube partly in shadow'),
    S('specular_streak', W=800, H=600, um=450 / 26, od_um=450, L_um=9000, heading=-15.0,
      bend=140, spec=dict(k=1.3, w=0.07, dir=60.0, off=0.5), a_w=0.35,
      description='glossy tube: a thin saturated specular highlight runs along the tube, '
                  'off-centre and moving across the width with the local orientation; pipette '
                  'from the left at -15 deg; 0 -> 140 deg; 26 px wide; MJPG',
      tests='bright line inside the dark tube (tube looks split)'),
    S('dye_blue_only_rgb_png', W=640, H=480, um=350 / 16, L_um=9000, bend=200,
      tint=[0.04, 0.08, 1.0], a_w=1.2, rim_k=0.15, NA=0.2, light=[1.0, 0.95, 0.85],
      glass_a=0.01, fmt='png_rgb',
      description='yellow-dyed tube in colour: only the blue channel carries contrast '
                  '(red/green show only faint refraction rims), weak rims; pipette from the '
                  'left; 0 -> 200 deg; RGB PNG folder',
      tests='contrast in one colour channel only (luma has ~12 % of it)'),
    S('polar_contrast_inversion', W=640, H=480, um=350 / 18, L_um=9000, bend=170,
      a_w=0.0, rim_k=0.5, NA=0.15, polar=dict(c0=-0.30, c1=0.50), level=0.5,
      fmt='avi:FFV1', glass_a=0.0,
      description='partly crossed polarisers: the tube fill is darker than the background at '
                  'rest and brighter when strained (birefringence grows with pressure); the sign '
                  'of the contrast inverts mid-video; weak rims; pipette from the left; '
                  '0 -> 170 deg; FFV1',
      tests='low contrast whose sign inverts over time'),
    # ---- holders / scene
    S('glue_blob_mov', W=640, H=480, um=350 / 16, L_um=9000, heading=20.0, bend=180,
      glue=dict(R=3.2, amp=[0.10, 0.06, 0.05], a=1.6, dn=0.12, pip_end=0.55),
      fmt='mov:mp4v',
      description='epoxy blob (irregular dome, ~3 tube radii) glues the tube into the '
                  'pipette; the base is where the tube leaves the blob; pipette from the left at '
                  '20 deg; 0 -> 180 deg; QuickTime .mov (mp4v; H.264 is not available in this '
                  'OpenCV)',
      tests='base at a glue blob, not at the glass end face; MOV container'),
    S('wide_bright_pipette_f32', W=640, H=480, um=350 / 14, L_um=8500, bend=160,
      pip_ro=80.0 / 7, pip_ri=1.7, glass_glow=0.45, glass_a=0.02, fmt='tif_f32', n=20,
      description='thick glass capillary 160 px wide (a third of the frame height) that '
                  'pipes light and is brighter than the background, bore 24 px; tube 14 px '
                  'wide; 0 -> 160 deg; float32 ImageJ TIFF stack (values ~0-4000)',
      tests='dominant bright holder; float32 TIFF'),
    S('needle_sleeve_rgba', W=720, H=540, um=350 / 17, L_um=9000, heading=195.0, bend=-150,
      holder='sleeve', sleeve=dict(ro=2.1, ri=1.03, a=0.45, dn=0.10, needle_r=0.5,
                                   needle_end=2.5), fmt='png_rgba',
      description='two-part holder from the right (heading 195 deg): a steel needle inside '
                  'the tube lumen, both inside a translucent plastic sleeve; the base is the '
                  'sleeve end face; 0 -> -150 deg; RGBA PNG folder (alpha = 255)',
      tests='compound holder; the needle end is not the base; RGBA PNG'),
    S('midframe_diag_pipette_palette', W=800, H=600, um=350 / 16, L_um=8500, heading=-30.0,
      bend=200, place='manual', base_px=(330.0, 240.0), fmt='png_pal',
      description='base mid-frame: the pipette runs diagonally out of the upper-left corner '
                  '(tube heading -30 deg), 0 -> 200 deg; indexed/palette PNG (64 adaptive '
                  'colours, palette order not monotonic)',
      tests='base far from any border; palette PNG'),
    S('grid_paper_tif12_t001', W=800, H=600, um=300 / 14, od_um=300, L_um=9000, bend=180,
      grid=dict(pitch_um=1000.0, w_um=60.0, c=0.28, major=5, ang=7.0, blur=1.5),
      fmt='tif12_folder',
      description='printed mm grid paper under the dish (dark lines every 1 mm, heavier every '
                  '5 mm, rotated 7 deg); pipette from the left; 0 -> 180 deg; folder of '
                  '16-bit TIFFs img_t001_c0.tif ... with 12-bit data left-aligned (x16)',
      tests='straight line clutter crossing the tube; 12-bit-in-16 MSB-aligned; file names'),
    S('meniscus_line_ffv1', W=640, H=480, um=350 / 16, L_um=9000, heading=0.0, bend=170,
      meniscus=dict(y0=0.62, curv=0.0004, ang=-8.0, w=5.0, step=0.22, line=0.45),
      fmt='avi:FFV1',
      description='water meniscus: a curved dark/bright line across the whole field with a '
                  'brightness step across it, the tube crosses it while bending; pipette from '
                  'the left; 0 -> 170 deg; FFV1',
      tests='long curved non-tube edge'),
    S('jpeg_q30_folder', W=640, H=480, um=350 / 15, L_um=9000, heading=225.0, bend=-160,
      fmt='jpg30',
      description='heavy JPEG compression (quality 30, 8x8 blocking) in a folder; pipette from '
                  'the upper right (heading 225 deg), 0 -> -160 deg',
      tests='blocking/ringing artefacts'),
    # ---- motion / optics
    S('motion_blur_fast', W=640, H=480, um=350 / 14, L_um=9000, bend=150, p='smooth_window',
      p_args=dict(a=3, b=21), blur=dict(expo=0.5, K=15),
      description='fast inflation (up to 12.5 deg/frame) filmed with an exposure of half the '
                  'frame interval: moving parts smear along their motion (tip smear ~20 px); '
                  'truth at mid-exposure; pipette from the left; MJPG',
      tests='motion blur'),
    S('twist_lumen_swap', W=640, H=480, um=400 / 24, od_um=400, L_um=9000, bend=140,
      ecc=0.75, id_frac=0.55, twist=dict(phi0=0.0, phi1=math.pi), fmt='avi:FFV1',
      description='air-filled strongly eccentric lumen that rotates about the tube axis '
                  '(torsion): the dark lumen line moves from one side of the tube to the other '
                  'over the video; pipette from the left; 0 -> 140 deg; FFV1',
      tests='interior line that swaps sides (must track the outer edges)'),
    S('camera_shake', W=640, H=480, um=350 / 16, L_um=9000, bend=170,
      shake=dict(sd=0.6, bumps={8: (4.0, -3.0), 9: (2.5, -2.0), 17: (-5.0, 2.5)}),
      description='camera shake: the whole scene (pipette, base and tube) jitters by '
                  '~0.6 px per frame, with bumps of up to 5.6 px at frames 8, 9 and 17; '
                  'vignetting stays fixed; pipette from the left; 0 -> 170 deg; MJPG',
      tests='moving base/holder'),
    S('focus_drift_autogain', W=640, H=480, um=350 / 16, L_um=9000, bend=-170,
      psf_t=dict(kind='drift', s0=0.7, s1=4.0, s2=1.6), gain_t=dict(a=0.22, per=11.0),
      fmt='avi:FFV1',
      description='slow focus drift (Gaussian PSF sigma 0.7 -> 4.0 -> 1.6 px) and auto-gain '
                  'pumping (+-22 %, period 11 frames); pipette from the left; 0 -> -170 deg; '
                  'FFV1',
      tests='time-varying blur and brightness'),
    # ---- kinematics
    S('small_angle_8deg', W=1024, H=576, um=400 / 20, od_um=400, L_um=10000, bend=8.0,
      p='ramp', n=20, fmt='avi:FFV1', heading=3.0,
      description='tiny bend: 0 -> 8 deg total, linear; 1024x576, tube 20 px wide, 500 px '
                  'long, pipette from the left at 3 deg; FFV1',
      tests='precision of small bends'),
    S('sign_reversal_tif16narrow', W=640, H=480, um=350 / 16, L_um=9000, rest=-40.0,
      bend=120.0, fracs=[0.45, 0.55], ratios=[1.0, 1.3], heading=15.0, fmt='tif16narrow',
      description='bent -40 deg at rest, ends +120 deg (passes through straight); 2 sections; '
                  'pipette from the left at 15 deg; 16-bit TIFF stack using only 1000-1400',
      tests='sign reversal of the bend; narrow 16-bit range'),
    S('pressure_steps_plateaus', W=640, H=480, um=350 / 16, L_um=9000, bend=220, n=36,
      p='steps', p_args=dict(levels=[0.0, 0.25, 0.5, 0.8, 1.0, 0.6], hold=6),
      description='pressure steps: 6 plateaus held 6 frames each, jumps of up to 66 deg '
                  'between frames; pipette from the left; up to 220 deg; MJPG',
      tests='held plateaus with sudden jumps'),
    S('curl_720_spiral', W=1024, H=768, um=300 / 12, od_um=300, L_um=12000,
      fracs=[0.35, 0.35, 0.30], ratios=[0.55, 1.0, 1.6], bend=720.0, n=30, fmt='avi:FFV1',
      description='curl to two full turns (720 deg) as an inward spiral (3 sections '
                  '0.55:1:1.6), crossing its own body and the pipette; 1024x768, 12 px wide; '
                  'FFV1',
      tests='two turns: unwrapping and crossings'),
    S('short_stub_1280', W=1280, H=960, um=400 / 24, od_um=400, L_um=1500, bend=70.0,
      id_frac=0.5, n=20,
      description='a very short free stub: 1.5 mm (90 px, under 4 diameters) of a 24 px wide '
                  'tube sticks out of a pipette that crosses half of a 1280x960 frame; '
                  '0 -> 70 deg; MJPG',
      tests='tiny tube relative to the frame; cap is a large part of it'),
    S('long_slow_480_small', W=320, H=240, um=300 / 8, od_um=300, L_um=8000, bend=60.0,
      n=480, fps=30.0, p='ramp', psf=0.8,
      description='480 frames of 320x240 at 30 fps: very slow bend 0 -> 60 deg (0.125 '
                  'deg/frame, many near-identical frames); tube 8 px wide; pipette from the '
                  'left; MJPG',
      tests='long video; slow change; drift'),
    S('letterbox_mjpg', W=800, H=600, um=350 / 16, L_um=9000, bend=180,
      letterbox=dict(top=75, bottom=75, left=0, right=0),
      description='800x600 frames whose active area is 800x450: black bars 75 px at top and '
                  'bottom; pipette from the left; 0 -> 180 deg; MJPG',
      tests='black border inside the frame'),
]
BY_NAME = {s['name']: s for s in SCENE_LIST}


# --------------------------------------------------------------------------------------------
def pressure(sc, tau):
    n = sc['n']
    x = tau / max(1, n - 1)
    kind = sc['p']
    if kind == 'ramp':
        return float(np.clip(x, 0, 1))
    if kind == 'ease':
        x = np.clip(x, 0, 1)
        return float(x * x * (3 - 2 * x))
    if kind == 'smooth_window':
        a, b = sc['p_args']['a'], sc['p_args']['b']
        x = np.clip((tau - a) / (b - a), 0, 1)
        return float(x * x * (3 - 2 * x))
    if kind == 'steps':
        lv, hold = sc['p_args']['levels'], sc['p_args']['hold']
        i = int(min(len(lv) - 1, max(0, math.floor(tau / hold + 1e-9))))
        return float(lv[i])
    raise ValueError(kind)


def px_params(sc):
    um = sc['um']
    ro = sc['od_um'] / 2 / um
    ri = ro * sc['id_frac']
    L0 = sc['L_um'] / um
    fr = np.array(sc['fracs'], float)
    fr = fr / fr.sum()
    lens0 = L0 * fr
    r = np.array(sc['ratios'], float)
    rr = np.array(sc['rest_ratios'] or sc['ratios'], float)
    eps = sc['elong']
    rest = math.radians(sc['rest'])
    bend = math.radians(sc['bend'])
    krest = rest * rr / (rr * lens0).sum()
    K = (bend - rest * (1 + eps)) / ((r * lens0).sum() * (1 + eps))
    return dict(ro=ro, ri=ri, lens0=lens0, r=r, krest=krest, K=K, eps=eps)


def chain_at(sc, pp, base, tau):
    p = pressure(sc, tau)
    lens = pp['lens0'] * (1 + pp['eps'] * p)
    kaps = pp['krest'] + pp['r'] * pp['K'] * p
    return Chain(base, math.radians(sc['heading']), lens, kaps)


def placement(sc, pp):
    """base in canvas-free image px coords (col,row)."""
    W, H = sc['W'], sc['H']
    ro = pp['ro']
    pts = []
    for f in range(sc['n']):
        ch = chain_at(sc, pp, (0.0, 0.0), f)
        s = np.linspace(0, ch.L, 400)
        P, _ = ch.points(s)
        pts.append(P)
    P = np.concatenate(pts)
    cols, rows = P[:, 0], -P[:, 1]
    lo_c, hi_c = cols.min() - ro, cols.max() + ro
    lo_r, hi_r = rows.min() - ro, rows.max() + ro
    pl = sc['place']
    if pl == 'manual':
        return np.array(sc['base_px'], float)
    if pl == 'auto':
        bc = (W - 1) / 2 - (lo_c + hi_c) / 2 + sc['bias'][0]
        br = (H - 1) / 2 - (lo_r + hi_r) / 2 + sc['bias'][1]
        return np.array([bc, br])
    side = pl.split(':')[1]
    if side == 'bottom':
        br = H - 0.5
        bc = (W - 1) / 2 - (lo_c + hi_c) / 2
        return np.array([bc, br])
    if side == 'left':
        return np.array([-0.5, (H - 1) / 2 - (lo_r + hi_r) / 2])
    raise ValueError(pl)


# --------------------------------------------------------------------------------------------
class Frame:
    """renders one frame (linear intensity, channels-last float32) on a padded canvas."""

    def __init__(self, sc, pp, pad):
        self.sc, self.pp, self.pad = sc, pp, pad
        self.Wc, self.Hc = sc['W'] + 2 * pad, sc['H'] + 2 * pad
        self.nch = 3 if (sc['tint'] is not None or sc['light'] is not None) else 1

    def band_mask(self, ch, base_c, extra_masks):
        sc, ro = self.sc, self.pp['ro']
        Wc, Hc = self.Wc, self.Hc
        s = np.arange(-3 * (Wc + Hc), ch.L + 0.25, 0.5)
        s = s[s > -2.5 * (Wc + Hc)]
        P, _ = ch.points(np.append(s, ch.L))
        c = np.round(P[:, 0]).astype(int)
        r = np.round(-P[:, 1]).astype(int)
        m = (c >= 0) & (c < Wc) & (r >= 0) & (r < Hc)
        mask = np.zeros((Hc, Wc), np.uint8)
        mask[r[m], c[m]] = 1
        rad = int(math.ceil(ro + 2.5))
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * rad + 1, 2 * rad + 1))
        mask = cv2.dilate(mask, k)
        for em in extra_masks:
            mask |= em
        return mask

    def render(self, ch, tau, base_c, field=None):
        """ch: chain in canvas math coords. returns linear image (Hc,Wc,nch)."""
        sc, pp = self.sc, self.pp
        ro, ri = pp['ro'], pp['ri']
        Wc, Hc = self.Wc, self.Hc
        th0 = math.radians(sc['heading'])
        t0, n0 = tvec(th0), nvec(th0)
        B = ch.base
        # holder geometry masks (pixel centres)
        cc, rr = np.meshgrid(np.arange(Wc, dtype=np.float64), np.arange(Hc, dtype=np.float64))
        Xp, Yp = cc, -rr
        u_p = (Xp - B[0]) * t0[0] + (Yp - B[1]) * t0[1]
        v_p = -(Xp - B[0]) * t0[1] + (Yp - B[1]) * t0[0]
        extra = []
        hold = sc['holder']
        if hold == 'pipette':
            extra.append(((np.abs(v_p) <= sc['pip_ro'] * ro + 2.5) & (u_p <= 2.5)).astype(np.uint8))
        elif hold == 'clamp':
            extra.append(((np.abs(v_p) <= sc['clamp_hw'] * ro + 2.5) & (u_p <= 2.5)).astype(np.uint8))
        elif hold == 'sleeve':
            extra.append(((np.abs(v_p) <= sc['sleeve']['ro'] * ro + 2.5) & (u_p <= 2.5)).astype(np.uint8))
        g = sc['glue']
        if g is not None:
            Rb = g['R'] * ro
            Cb = B - Rb * t0
            extra.append((np.hypot(Xp - Cb[0], Yp - Cb[1]) <= Rb * (1 + sum(g['amp']) * 2) + 2.5)
                         .astype(np.uint8))
        mask = self.band_mask(ch, base_c, extra)
        rows, cols = np.nonzero(mask)
        N = len(rows)
        X = (cols[:, None] + OX[None, :]).ravel()
        Y = (-(rows[:, None] + OY[None, :])).ravel()
        F = {k: np.zeros(N * S2) for k in ('A', 'R', 'D', 'Gu', 'Fill', 'HL', 'E')}
        look = sc['look']
        lam = np.array([math.cos(math.radians(sc['obl_dir'])),
                        math.sin(math.radians(sc['obl_dir']))])
        NA = sc['NA']

        def add_grad(sel, gx, gy, dn_scale=1.0):
            gm = np.hypot(gx, gy)
            F['R'][sel] += sc['rim_k'] * np.log1p((gm / NA) ** 2)
            if look == 'df':
                q = (gm / sc['NA_df']) ** 4
                F['D'][sel] += q / (1 + q)
            if look == 'obl':
                F['Gu'][sel] += gx * lam[0] + gy * lam[1]

        # ---------------- tube
        L = ch.L
        Rc = ro
        if sc['cap'] == 'round':
            lum_end = L - Rc - 0.5 * (ro - ri)
        else:
            lum_end = L - (ro - ri)
        e_lat = sc['ecc'] * (ro - ri)
        if sc['twist'] is not None:
            tw = sc['twist']
            ph = tw['phi0'] + (tw['phi1'] - tw['phi0']) * tau / max(1, sc['n'] - 1)
            e_lat = e_lat * math.cos(ph)
        pc_x = cols.astype(float)
        pc_y = -rows.astype(float)
        pad_bb = ro + 1.5
        for i, (P0, tha, ka, la, s0a) in enumerate(ch.arcs):
            # bbox of the sub-arc
            sg = np.linspace(0, la, 9)
            Q = Chain._pt(P0, tha, ka, sg)
            if i == 0:  # back extension: only the part on/near the canvas matters
                pass
            x0, x1 = Q[:, 0].min() - pad_bb, Q[:, 0].max() + pad_bb
            y0, y1 = Q[:, 1].min() - pad_bb, Q[:, 1].max() + pad_bb
            if ka != 0:
                sag = la * la * abs(ka) / 8 + 0.01
                x0 -= sag; x1 += sag; y0 -= sag; y1 += sag
            pm = np.nonzero((pc_x >= x0) & (pc_x <= x1) & (pc_y >= y0) & (pc_y <= y1))[0]
            if len(pm) == 0:
                continue
            sel = (pm[:, None] * S2 + np.arange(S2)[None, :]).ravel()
            s, d, thF, valid = ch.foot(i, X[sel], Y[sel])
            valid &= s <= L
            if sc['cap'] == 'round':
                incap = s > L - Rc
                ro_s = np.where(incap, np.sqrt(np.maximum(Rc ** 2 - (s - (L - Rc)) ** 2, 0.0)), ro)
            else:
                incap = np.zeros(s.shape, bool)
                ro_s = np.full(s.shape, ro)
            valid &= np.abs(d) < ro_s
            if not valid.any():
                continue
            sel, s, d, thF, ro_s, incap = sel[valid], s[valid], d[valid], thF[valid], ro_s[valid], incap[valid]
            den_o = np.sqrt(np.maximum(ro_s ** 2 - d ** 2, 1e-6 * ro * ro))
            co = 2 * den_o
            dco = -2 * d / den_o
            has_l = (s < lum_end) & (np.abs(d - e_lat) < ri)
            den_l = np.sqrt(np.maximum(ri ** 2 - (d - e_lat) ** 2, 1e-6 * ro * ro))
            cl = np.where(has_l, 2 * den_l, 0.0)
            dcl = np.where(has_l, -2 * (d - e_lat) / den_l, 0.0)
            wall = co - cl
            gd = sc['dn_w'] * (dco - dcl) + sc['dn_l'] * dcl
            gs = np.where(incap, sc['dn_w'] * 2 * (-(s - (L - Rc))) / den_o, 0.0)
            kk = ka
            gs = gs / np.maximum(1 - kk * d, 0.2)
            ct, st = np.cos(thF), np.sin(thF)
            gx = gd * (-st) + gs * ct
            gy = gd * ct + gs * st
            F['A'][sel] += sc['a_w'] * wall / (2 * ro) + sc['a_l'] * cl / (2 * ro)
            add_grad(sel, gx, gy)
            F['Fill'][sel] += co / (2 * ro)
            if sc['spec'] is not None:
                sp = sc['spec']
                ld = np.array([math.cos(math.radians(sp['dir'])), math.sin(math.radians(sp['dir']))])
                ndot = (-st) * ld[0] + ct * ld[1]
                dh = sp['off'] * ro_s * ndot
                F['HL'][sel] += sp['k'] * np.exp(-0.5 * ((d - dh) / (sp['w'] * ro)) ** 2)
        # ---------------- holders
        u = (X - B[0]) * t0[0] + (Y - B[1]) * t0[1]
        v = -(X - B[0]) * t0[1] + (Y - B[1]) * t0[0]

        def glass(Ro, Ri, a, dn, glow, endu=0.0):
            m = (u < endu) & (np.abs(v) < Ro)
            if not m.any():
                return
            vv = v[m]
            deno = np.sqrt(np.maximum(Ro ** 2 - vv ** 2, 1e-6 * ro * ro))
            hasi = np.abs(vv) < Ri
            deni = np.sqrt(np.maximum(Ri ** 2 - vv ** 2, 1e-6 * ro * ro))
            gpath = 2 * deno - np.where(hasi, 2 * deni, 0.0)
            dg = -2 * vv / deno + np.where(hasi, 2 * vv / deni, 0.0)
            F['A'][m] += a * gpath / (2 * Ro) * 4
            add_grad(m, dn * dg * n0[0], dn * dg * n0[1])
            F['E'][m] += glow * gpath / (2 * Ro)
            # the cut end face scatters: a thin band inside the glass at its end
            fm = (u[m] > endu - 1.2) & (gpath > 0.05)
            idx = np.nonzero(m)[0][fm]
            if look == 'df':
                F['D'][idx] += 0.8
            else:
                F['R'][idx] += 0.8 * sc['rim_k']

        if hold == 'pipette':
            endu = -g['pip_end'] * g['R'] * ro if g is not None else 0.0
            glass(sc['pip_ro'] * ro, sc['pip_ri'] * ro, sc['glass_a'], sc['glass_dn'],
                  sc['glass_glow'], endu)
        elif hold == 'clamp':
            m = (u < 0) & (np.abs(v) < sc['clamp_hw'] * ro)
            F['A'][m] += 6.0
        elif hold == 'sleeve':
            sv = sc['sleeve']
            glass(sv['ro'] * ro, sv['ri'] * ro, sv['a'], sv['dn'], 0.0)
            m = (u < -sv['needle_end'] * ro) & (np.abs(v) < sv['needle_r'] * ro)
            F['A'][m] += 5.0
        if g is not None:
            Rb = g['R'] * ro
            Cb = B - Rb * t0
            dx, dy = X - Cb[0], Y - Cb[1]
            r = np.hypot(dx, dy)
            phi = np.arctan2(dx * n0[0] + dy * n0[1], dx * t0[0] + dy * t0[1])
            rb = Rb * self.blob_shape(phi)
            q = r / rb
            m = q < 1
            h = np.sqrt(np.maximum(1 - q[m] ** 2, 1e-6))
            F['A'][m] += g['a'] * h
            gr = g['dn'] * 2 * q[m] / h * (Rb / rb[m])
            # radial unit vector
            ux, uy = dx[m] / np.maximum(r[m], 1e-9), dy[m] / np.maximum(r[m], 1e-9)
            add_grad(m, gr * ux, gr * uy)
        # ---------------- look
        if field is not None:  # self-check: the area-averaged body indicator only
            img = np.zeros((Hc, Wc))
            img[rows, cols] = F[field].reshape(N, S2).mean(1)
            return img
        I = self.look(F, tau)
        Ip = I.reshape(N, S2, -1).mean(1)
        img = np.empty((Hc, Wc, self.nch))
        img[:] = self.look_bg(tau)
        img[rows, cols] = Ip
        return img

    def blob_shape(self, phi):
        g = self.sc['glue']
        out = np.ones_like(phi)
        ph = [0.7, 2.1, 4.0]
        for j, a in enumerate(g['amp']):
            k = j + 2
            out += a * (np.cos(k * phi + ph[j]) - math.cos(ph[j]))
        return out

    def chan_light(self):
        lt = self.sc['light']
        if self.nch == 1:
            return np.ones(1)
        return np.array(lt if lt is not None else [1, 1, 1], float)

    def look_bg(self, tau):
        sc = self.sc
        if sc['look'] == 'df':
            return np.full(self.nch, 0.04)
        return self.chan_light()

    def look(self, F, tau):
        sc = self.sc
        lk = sc['look']
        lt = self.chan_light()
        if lk == 'df':
            v = 0.04 + 0.9 * (1 - np.exp(-1.4 * F['D'])) + 0.03 * F['Fill']
            return v[:, None] * np.ones(self.nch)
        if self.nch == 3:
            tint = np.array(sc['tint'] if sc['tint'] is not None else [1, 1, 1], float)
            T = np.exp(-F['A'][:, None] * tint[None, :] - F['R'][:, None])
        else:
            T = np.exp(-F['A'] - F['R'])[:, None]
        if lk == 'obl':
            T = np.exp(-F['A'])[:, None] * (1 + sc['obl_k'] * np.tanh(F['Gu'] / sc['obl_c']))[:, None]
        if lk == 'bf' and sc['polar'] is not None:
            c = sc['polar']['c0'] + sc['polar']['c1'] * pressure(sc, tau)
            T = T * (1 + c * np.minimum(F['Fill'], 1.6))[:, None]
        T = T * lt[None, :]
        T = T + F['E'][:, None] + F['HL'][:, None]
        return T


# --------------------------------------------------------------------------------------------
def illumination(sc, f, pad):
    W, H = sc['W'] + 2 * pad, sc['H'] + 2 * pad
    cc, rr = np.meshgrid(np.arange(W, dtype=np.float64) - pad, np.arange(H, dtype=np.float64) - pad)
    xc, yc = (sc['W'] - 1) / 2, (sc['H'] - 1) / 2
    rad2 = ((cc - xc) ** 2 + (rr - yc) ** 2) / (xc ** 2 + yc ** 2)
    ill = 1 - sc['vig'] * rad2
    ga, gang = sc['grad']
    ill *= 1 + ga * ((cc - xc) * math.cos(math.radians(gang)) - (rr - yc) * math.sin(math.radians(gang))) / max(xc, yc)
    um = sc['um']
    if sc['grid'] is not None:
        gr = sc['grid']
        a = math.radians(gr['ang'])
        xu = (cc * math.cos(a) + rr * math.sin(a)) * um
        yu = (-cc * math.sin(a) + rr * math.cos(a)) * um
        lines = np.zeros_like(cc)
        for q in (xu, yu):
            k = np.round(q / gr['pitch_um'])
            dist = np.abs(q - k * gr['pitch_um'])
            w = np.where(np.mod(k, gr['major']) == 0, 2.0, 1.0) * gr['w_um'] / 2
            lines = np.maximum(lines, (dist < w).astype(float))
        lines = cv2.GaussianBlur(lines, (0, 0), gr['blur'])
        ill *= 1 - gr['c'] * lines
    if sc['meniscus'] is not None:
        mn = sc['meniscus']
        a = math.radians(mn['ang'])
        x = cc - xc
        yl = mn['y0'] * sc['H'] + x * math.tan(a) + mn['curv'] * x * x
        dd = (rr - yl) * math.cos(a)
        ill *= 1 - mn['step'] / (1 + np.exp(-dd / 3.0))
        ill *= 1 - mn['line'] * np.exp(-0.5 * (dd / mn['w']) ** 2) + 0.3 * np.exp(-0.5 * ((dd + 2.2 * mn['w']) / (0.6 * mn['w'])) ** 2)
    if sc['shadow'] is not None:
        sh = sc['shadow']
        x = f / max(1, sc['n'] - 1)
        c = np.array(sh['c0']) + (np.array(sh['c1']) - np.array(sh['c0'])) * x
        dist = np.hypot(cc - c[0], rr - c[1]) - sh['r']
        ill *= 1 - sh['depth'] / (1 + np.exp(dist / (sh['soft'] / 4)))
    return ill


def psf_sigma(sc, f):
    pt = sc['psf_t']
    if pt is None:
        return sc['psf']
    x = f / max(1, sc['n'] - 1)
    if x < 0.55:
        return pt['s0'] + (pt['s1'] - pt['s0']) * (x / 0.55) ** 1.5
    return pt['s1'] + (pt['s2'] - pt['s1']) * ((x - 0.55) / 0.45)


def shake_offset(sc, f):
    sh = sc['shake']
    if sh is None:
        return np.zeros(2)
    rng = np.random.default_rng(seed_of(sc['name'], 7000 + f))
    o = rng.normal(0, sh['sd'], 2)
    if f in sh['bumps']:
        o = o + np.array(sh['bumps'][f])
    return o  # (dcol, drow)


def render_scene(sc, out_root=SCENES):
    t_start = time.time()
    name = sc['name']
    pp = px_params(sc)
    ro = pp['ro']
    kmax = max(abs(pp['krest'] + pp['r'] * pp['K'] * p).max() for p in (0.0, 0.5, 1.0))
    assert kmax * ro < 0.8, (name, 'curvature too high', kmax * ro)
    base_img = placement(sc, pp)
    W, H, n = sc['W'], sc['H'], sc['n']
    pad = 16
    fr = Frame(sc, pp, pad)
    d = os.path.join(out_root, name)
    if os.path.exists(d):
        shutil.rmtree(d)
    os.makedirs(d)
    rng = np.random.default_rng(seed_of(name))
    prnu = 1 + 0.004 * rng.standard_normal((H, W))
    tracks, cl_rows, frames = [], [], []
    warn = []
    for f in range(n):
        off = shake_offset(sc, f)
        bcol, brow = base_img[0] + off[0], base_img[1] + off[1]
        base_c = np.array([bcol + pad, -(brow + pad)])
        taus = [float(f)]
        if sc['blur'] is not None:
            K, ex = sc['blur']['K'], sc['blur']['expo']
            taus = [f + (k / (K - 1) - 0.5) * ex for k in range(K)]
        acc = None
        for tau in taus:
            ch = chain_at(sc, pp, base_c, tau)
            im = fr.render(ch, tau, base_c)
            acc = im if acc is None else acc + im
        img = acc / len(taus)
        img = img * illumination(sc, f, pad)[:, :, None]
        sig = psf_sigma(sc, f)
        if sig > 0.05:
            img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), sig,
                                   borderType=cv2.BORDER_REFLECT)
            if img.ndim == 2:
                img = img[:, :, None]
        img = np.asarray(img, np.float64)[pad:pad + H, pad:pad + W]
        gain = 1.0
        if sc['gain_t'] is not None:
            gain = 1 + sc['gain_t']['a'] * math.sin(2 * math.pi * f / sc['gain_t']['per'])
        val = sc['level'] * gain * img * prnu[:, :, None]
        frng = np.random.default_rng(seed_of(name, 1 + f))
        val = val + frng.standard_normal(val.shape) * np.sqrt(sc['rn'] ** 2 + sc['shot'] * np.maximum(val, 0))
        if sc['letterbox'] is not None:
            lb = sc['letterbox']
            act = np.zeros((H, W), bool)
            act[lb['top']:H - lb['bottom'], lb['left']:W - lb['right']] = True
            val[~act] = 0.0
        val = np.clip(val, 0, 1)
        frames.append(val.astype(np.float32))
        # truth (at the frame's own time = mid-exposure)
        ch = chain_at(sc, pp, np.array([bcol, -brow]), float(f))
        L = ch.L
        kab = np.abs(np.array(ch.kaps))
        tot = float((np.array(ch.lens) * kab ** 2).sum())
        ds = 0.35 if tot == 0 else min(0.35, math.sqrt(0.002 * 24 / tot))
        m = int(math.ceil(L / ds))
        s = np.linspace(0, L, m + 1)
        dl = 0.002
        s = np.unique(np.concatenate([s, [dl, L - dl]]))
        P, _ = ch.points(s)
        P[-1] = ch.tip
        for si, (x, y) in zip(s, P):
            cl_rows.append((f, si * sc['um'], x * sc['um'], y * sc['um']))
        tracks.append((f, f / sc['fps'], math.degrees(ch.bend), ch.tip[0] * sc['um'],
                       ch.tip[1] * sc['um'], bcol * sc['um'], -brow * sc['um'], L * sc['um'], 'ok'))
        # margins
        ccol, crow = P[:, 0], -P[:, 1]
        mg = min(ccol.min(), crow.min(), W - 1 - ccol.max(), H - 1 - crow.max()) - ro
        if sc['place'] != 'border:bottom' and sc['place'] != 'border:left' and mg < 3:
            warn.append('frame %d margin %.1f px' % (f, mg))
        if sc['place'].startswith('border'):
            inner = P[s > 3 * ro]
            mg2 = min(inner[:, 0].min(), (-inner[:, 1]).min(), W - 1 - inner[:, 0].max(),
                      H - 1 - (-inner[:, 1]).max()) - ro
            if mg2 < 3:
                warn.append('frame %d inner margin %.1f px' % (f, mg2))
        if sc['glue'] is not None:
            # the centreline beyond the base must be outside the blob
            g = sc['glue']
            Rb = g['R'] * ro
            B = np.array([bcol, -brow])
            t0, n0 = tvec(math.radians(sc['heading'])), nvec(math.radians(sc['heading']))
            Cb = B - Rb * t0
            Q = P[s > 0.01] - Cb
            phi = np.arctan2(Q @ n0, Q @ t0)
            inside = np.hypot(Q[:, 0], Q[:, 1]) < Rb * fr.blob_shape(phi)
            assert not inside.any(), (name, f, 'centreline inside blob')
    write_frames(sc, d, frames)
    rb_ok, rb_msg = readback_check(sc, d, frames)
    if not rb_ok:
        warn.append('READBACK ' + rb_msg)
    with open(os.path.join(d, 'truth_tracks.csv'), 'w') as fh:
        fh.write('frame,time_s,bend_angle_deg,tip_x_um,tip_y_um,base_x_um,base_y_um,length_um,status\n')
        for t in tracks:
            fh.write('%d,%.6f,%.6f,%.5f,%.5f,%.5f,%.5f,%.5f,%s\n' % t)
    with open(os.path.join(d, 'truth_centrelines.csv'), 'w') as fh:
        fh.write('frame,s_um,x_um,y_um\n')
        for t in cl_rows:
            fh.write('%d,%.5f,%.5f,%.5f\n' % t)
    meta = dict(
        name=name, description=sc['description'], tests=sc['tests'], um_per_px=sc['um'],
        input=INPUT_OF[fmt_kind(sc['fmt'])], n_frames=n, fps=sc['fps'], frame_size=[W, H],
        settings={k: (v if not isinstance(v, dict) else {str(a): b for a, b in v.items()})
                  for k, v in sc.items()},
        derived=dict(ro_px=ro, ri_px=pp['ri'], lumen_offset_px=sc['ecc'] * (ro - pp['ri']),
                     base_px_frame0=list(map(float, base_img)), lens0_px=list(pp['lens0']),
                     kappa_rest_per_px=list(pp['krest']), K_per_px=pp['K'],
                     ratios=list(pp['r']), seed=seed_of(name),
                     fourcc=sc['fmt'].split(':')[1] if ':' in sc['fmt'] else None,
                     warnings=warn, readback=rb_msg),
        conventions=dict(
            pixel_centre='pixel (col,row) has its centre at (col,row)',
            axes='x_um = col*um_per_px, y_um = -row*um_per_px (y up)',
            bend='unwrapped CCW rotation of the tip tangent relative to the base tangent, '
                 'both pointing base->tip (deg); clockwise negative',
            base='where the tube leaves its holder (pipette end face / sleeve end face / glue '
                 'blob surface); with no holder where the centreline crosses the outer pixel '
                 'edge of the image border',
            tip='physical end: apex of the round cap (the cap follows the bending centreline)',
            truth_time='mid-exposure (frame time f/fps)',
            truth_centrelines='exact points on the arcs, <= 0.35 px apart (plus points 0.002 px '
                              'from each end), base -> tip'))
    with open(os.path.join(d, 'scene.json'), 'w') as fh:
        json.dump(meta, fh, indent=1, default=lambda o: o.tolist() if hasattr(o, 'tolist') else str(o))
    dt = time.time() - t_start
    print('  %-32s %4d frames %5.1fs %s' % (name, n, dt, ('WARN ' + '; '.join(warn[:3])) if warn else ''),
          flush=True)
    return name, dt, warn


# --------------------------------------------------------------------------------------------
def fmt_kind(fmt):
    return fmt.split(':')[0]


INPUT_OF = {'avi': 'video.avi', 'mkv': 'video.mkv', 'mov': 'video.mov', 'mp4': 'video.mp4',
            'png': 'frames', 'png_rgb': 'frames', 'png_rgba': 'frames', 'png_pal': 'frames',
            'jpg30': 'frames', 'tif8': 'stack.tif', 'tif16narrow': 'stack.tif',
            'tif_f32': 'stack.tif', 'tif12_folder': 'frames'}


def to8(v):
    return np.clip(np.round(v * 255), 0, 255).astype(np.uint8)


def bgr(v):
    if v.shape[2] == 1:
        return np.repeat(to8(v), 3, 2)
    return to8(v)[:, :, ::-1]


def write_frames(sc, d, frames):
    fmt = sc['fmt']
    kind = fmt_kind(fmt)
    H, W = sc['H'], sc['W']
    if kind in ('avi', 'mkv', 'mov', 'mp4'):
        fourcc = fmt.split(':')[1]
        w = cv2.VideoWriter(os.path.join(d, INPUT_OF[kind]), cv2.VideoWriter_fourcc(*fourcc),
                            sc['fps'], (W, H), True)
        assert w.isOpened(), fmt
        for v in frames:
            w.write(bgr(v))
        w.release()
        return
    if kind == 'tif8':
        tifffile.imwrite(os.path.join(d, 'stack.tif'), np.stack([to8(v[:, :, 0]) for v in frames]),
                         photometric='minisblack')
        return
    if kind == 'tif16narrow':
        a = np.stack([np.round(1000 + 400 * v[:, :, 0]).astype(np.uint16) for v in frames])
        tifffile.imwrite(os.path.join(d, 'stack.tif'), a, photometric='minisblack')
        return
    if kind == 'tif_f32':
        a = np.stack([(v[:, :, 0] * 4000.0).astype(np.float32) for v in frames])
        tifffile.imwrite(os.path.join(d, 'stack.tif'), a, imagej=True, metadata={'axes': 'TYX'})
        return
    fd = os.path.join(d, 'frames')
    os.makedirs(fd)
    for i, v in enumerate(frames):
        if kind == 'png':
            cv2.imwrite(os.path.join(fd, 'frame_%04d.png' % i), to8(v[:, :, 0]))
        elif kind == 'png_rgb':
            cv2.imwrite(os.path.join(fd, 'frame_%04d.png' % i), bgr(v))
        elif kind == 'png_rgba':
            b = bgr(v)
            a = np.full((H, W, 1), 255, np.uint8)
            cv2.imwrite(os.path.join(fd, 'frame_%04d.png' % i), np.concatenate([b, a], 2))
        elif kind == 'png_pal':
            im = Image.fromarray(to8(v[:, :, 0])).convert('RGB').quantize(colors=64, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
            im.save(os.path.join(fd, 'frame_%04d.png' % i))
        elif kind == 'jpg30':
            cv2.imwrite(os.path.join(fd, 'frame_%04d.jpg' % i), to8(v[:, :, 0]),
                        [cv2.IMWRITE_JPEG_QUALITY, 30])
        elif kind == 'tif12_folder':
            a12 = np.clip(np.round(v[:, :, 0] * 4095), 0, 4095).astype(np.uint16)
            tifffile.imwrite(os.path.join(fd, 'img_t%03d_c0.tif' % (i + 1)), a12 << 4,
                             photometric='minisblack')
        else:
            raise ValueError(kind)


# --------------------------------------------------------------------------------------------
# checks
def natural_key(s):
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r'(\d+)', s)]


def read_back(d, meta):
    inp = os.path.join(d, meta['input'])
    if os.path.isdir(inp):
        names = sorted(os.listdir(inp), key=natural_key)
        out = []
        for nm in names:
            if nm.endswith('.tif'):
                out.append(tifffile.imread(os.path.join(inp, nm)).astype(np.float64))
            else:
                im = cv2.imread(os.path.join(inp, nm), cv2.IMREAD_UNCHANGED)
                if im.ndim == 3:
                    im = cv2.cvtColor(im[:, :, :3], cv2.COLOR_BGR2GRAY) if im.shape[2] >= 3 else im[:, :, 0]
                out.append(im.astype(np.float64))
        return out, names
    if inp.endswith('.tif'):
        a = tifffile.imread(inp)
        return [x.astype(np.float64) for x in a], None
    cap = cv2.VideoCapture(inp)
    out = []
    while True:
        ok, im = cap.read()
        if not ok:
            break
        out.append(cv2.cvtColor(im, cv2.COLOR_BGR2GRAY).astype(np.float64))
    return out, None


def check_conventions():
    lines = []
    # 1. straight rod with its axis exactly on row 100.0 (solid, no blur, absorbing only)
    sc = S('_rod', W=200, H=200, holder=None, heading=0.0, bend=0.0, id_frac=0.0, ecc=0.0,
           rim_k=0.0, a_w=1.0, psf=0.0, um=1.0, od_um=12.0, L_um=1000.0)
    pp = px_params(sc)
    fr = Frame(sc, pp, 0)
    for axis_row in (100.0, 100.25):
        ch = Chain(np.array([-0.5, -axis_row]), 0.0, [1000.0], [0.0])
        img = fr.render(ch, 0.0, None)[:, :, 0]
        a = -np.log(np.clip(img, 1e-12, None))  # per-pixel mean of T -> use 1-T as weight
        wgt = 1 - img
        rows = np.arange(200, dtype=float)
        cen = (wgt[:, 20:180] * rows[:, None]).sum(0) / wgt[:, 20:180].sum(0)
        lines.append('rod axis at row %.2f: profile centroid of (1-I) over cols 20..179 = %.5f '
                     '(min %.5f max %.5f)' % (axis_row, cen.mean(), cen.min(), cen.max()))
    # column axis
    ch = Chain(np.array([80.0, 0.5]), -math.pi / 2, [1000.0], [0.0])
    img = fr.render(ch, 0.0, None)[:, :, 0]
    wgt = 1 - img
    colsx = np.arange(200, dtype=float)
    cen = (wgt[20:180, :] * colsx[None, :]).sum(1) / wgt[20:180, :].sum(1)
    lines.append('rod axis at col 80.00 (entering from the top): centroid = %.5f' % cen.mean())
    # 2. sign: +90 deg from a base pointing right ends up and to the right
    ch = Chain(np.array([0.0, 0.0]), 0.0, [100.0], [math.pi / 2 / 100.0])
    lines.append('sign: base (0,0) heading 0, +90 deg over 100 px -> tip (x,y)=(%.3f, %.3f) '
                 '(y up; expect (63.662, 63.662)), tip heading %.3f deg; y_um>0 means up: %s'
                 % (ch.tip[0], ch.tip[1], math.degrees(ch.th_tip), ch.tip[1] > 0))
    # and its image: tip row must be smaller (higher on screen) than the base row
    lines.append('  in image coords the tip is at row %.3f < base row 0 -> up on screen' % (-ch.tip[1]))
    return lines


def _z(a):
    a = np.asarray(a, np.float64)
    return (a - a.mean()) / (a.std() + 1e-12)


def readback_check(sc, d, frames):
    """read the written frames back (OpenCV / tifffile, natural sort) and check count and order:
    every frame read back must be closer (z-scored MSE) to its own rendered frame than to the
    rendered frames before/after it and to the first and last."""
    meta = dict(input=INPUT_OF[fmt_kind(sc['fmt'])])
    got, _ = read_back(d, meta)
    n = len(frames)
    if len(got) != n:
        return False, 'count %d != %d' % (len(got), n)
    ref = [_z(f.mean(2)) for f in frames]
    bad = 0
    for i, g in enumerate(got):
        zg = _z(g)
        own = ((zg - ref[i]) ** 2).mean()
        for j in {i - 1, i + 1, 0, n - 1} - {i}:
            if 0 <= j < n and ((zg - ref[j]) ** 2).mean() < own:
                bad += 1
                break
    return bad == 0, 'read back %d frames, %d out of order' % (len(got), bad)


def turning_deg(P):
    dv = np.diff(P, axis=0)
    a = np.arctan2(dv[:, 1], dv[:, 0])
    da = np.diff(a)
    da = (da + np.pi) % (2 * np.pi) - np.pi
    return math.degrees(da.sum())


def check_scene(name):
    import pandas as pd
    d = os.path.join(SCENES, name)
    meta = json.load(open(os.path.join(d, 'scene.json')))
    um = meta['um_per_px']
    tr = pd.read_csv(os.path.join(d, 'truth_tracks.csv'))
    tc = pd.read_csv(os.path.join(d, 'truth_centrelines.csv'))
    worst_a = worst_l = worst_gap = worst_end = 0.0
    for f, g in tc.groupby('frame'):
        t = tr[tr.frame == f].iloc[0]
        P = np.stack([g.x_um.values, g.y_um.values], 1) / um
        worst_a = max(worst_a, abs(turning_deg(P) - t.bend_angle_deg))
        seg = np.hypot(*np.diff(P, axis=0).T)
        worst_l = max(worst_l, abs(seg.sum() - t.length_um / um))
        worst_gap = max(worst_gap, seg.max())
        e1 = math.hypot(P[0, 0] - t.base_x_um / um, P[0, 1] - t.base_y_um / um)
        e2 = math.hypot(P[-1, 0] - t.tip_x_um / um, P[-1, 1] - t.tip_y_um / um)
        worst_end = max(worst_end, e1, e2)
    frames, names = read_back(d, meta)
    n_ok = len(frames) == meta['n_frames'] == len(tr)
    # order check: re-render is expensive; use the fact that consecutive frames differ:
    # each frame read back must be closer to its own re-rendered ... approximated by checking the
    # truth tip: the darkest/brightest deviation near the truth tip moves with the truth.
    order_ok = True
    if names is not None:
        order_ok = names == sorted(names, key=natural_key) and all(
            int(re.findall(r'\d+', nm)[-2 if nm.startswith('img_t') else -1]) == i + (1 if nm.startswith('img_t') else 0)
            for i, nm in enumerate(names))
    shapes = {f.shape for f in frames}
    return dict(name=name, frames=len(frames), n_ok=n_ok, order_ok=order_ok,
                shape=str(shapes.pop() if len(shapes) == 1 else shapes),
                d_angle=worst_a, d_len=worst_l, gap=worst_gap, end=worst_end,
                rng='%.0f..%.0f' % (min(f.min() for f in frames), max(f.max() for f in frames)))


def check_body(name):
    """the rendered body is centred on the truth: render the area-averaged outer-chord indicator
    (co/2ro, independent of lumen and look) of the first, middle and last frame and take its
    centroid along the truth normals (bilinear samples every 0.25 px over +-1.6 ro) at truth points
    away from crossings, the cap and the image border."""
    import pandas as pd
    from scipy.ndimage import map_coordinates
    from scipy.spatial import cKDTree
    sc = dict(BY_NAME[name])
    sc['psf'] = 0.0
    pp = px_params(sc)
    ro = pp['ro']
    d = os.path.join(SCENES, name)
    tr = pd.read_csv(os.path.join(d, 'truth_tracks.csv'))
    tc = pd.read_csv(os.path.join(d, 'truth_centrelines.csv'))
    um = sc['um']
    fr = Frame(sc, pp, 0)
    offs = []
    n = sc['n']
    for f in sorted({0, n // 2, n - 1}):
        t = tr.iloc[f]
        ch = chain_at(sc, pp, np.array([t.base_x_um / um, t.base_y_um / um]), float(f))
        img = fr.render(ch, float(f), None, field='Fill')
        g = tc[tc.frame == f]
        s = g.s_um.values / um
        P = np.stack([g.x_um.values, g.y_um.values], 1) / um
        keep = (s > 2 * ro) & (s < ch.L - 2 * ro)
        keep &= np.arange(len(s)) % 8 == 0
        tree = cKDTree(P)
        Pk, sk = P[keep], s[keep]
        _, th = ch.points(sk)
        far = np.ones(len(sk), bool)
        for i, nb in enumerate(tree.query_ball_point(Pk, 2.6 * ro)):
            if np.any(np.abs(s[nb] - sk[i]) > 3.2 * ro):
                far[i] = False
        col, row = Pk[:, 0], -Pk[:, 1]
        far &= (col > 2 * ro + 3) & (row > 2 * ro + 3) & (col < sc['W'] - 2 * ro - 4) & (row < sc['H'] - 2 * ro - 4)
        if sc['letterbox'] is not None:
            pass
        q = np.arange(-1.6 * ro, 1.6 * ro + 1e-9, 0.25)
        for (cx, cy), a in zip(Pk[far], th[far]):
            nx, ny = -math.sin(a), math.cos(a)
            xs, ys = cx + q * nx, cy + q * ny
            v = map_coordinates(img, [-ys, xs], order=1)
            offs.append((v * q).sum() / v.sum())
    offs = np.abs(np.array(offs))
    return len(offs), np.median(offs), np.percentile(offs, 95), offs.max()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('-j', type=int, default=2)
    ap.add_argument('--only', nargs='*')
    ap.add_argument('--list', action='store_true')
    ap.add_argument('--check', action='store_true', help='run the self-checks (no rendering)')
    a = ap.parse_args()
    if a.list:
        for s in SCENE_LIST:
            print('%-32s %s' % (s['name'], s['tests']))
        return
    names = [s['name'] for s in SCENE_LIST]
    if a.only:
        bad = set(a.only) - set(names)
        if bad:
            sys.exit('unknown: %s' % sorted(bad))
        names = [n for n in names if n in a.only]
    if a.check:
        for ln in check_conventions():
            print(ln)
        print('%-32s %6s %5s %5s %-10s %9s %9s %7s %7s %s' % (
            'scene', 'frames', 'count', 'order', 'shape', 'dA deg', 'dL px', 'gap px', 'end px', 'range'))
        body = {}
        for nm in names:
            body[nm] = check_body(nm)
        for nm in names:
            r = check_scene(nm)
            print('%-32s %6d %5s %5s %-10s %9.5f %9.5f %7.3f %7.4f %s' % (
                r['name'], r['frames'], r['n_ok'], r['order_ok'], r['shape'], r['d_angle'],
                r['d_len'], r['gap'], r['end'], r['rng']))
        print()
        print('body centred on the truth (|centroid of the outer-chord indicator along the truth '
              'normal|, px):')
        print('%-32s %6s %8s %8s %8s' % ('scene', 'points', 'median', 'p95', 'max'))
        for nm in names:
            print('%-32s %6d %8.4f %8.4f %8.4f' % ((nm,) + tuple(body[nm])))
        return
    os.makedirs(SCENES, exist_ok=True)
    t0 = time.time()
    # big scenes first
    order = sorted(names, key=lambda n: -BY_NAME[n]['W'] * BY_NAME[n]['H'] * BY_NAME[n]['n']
                   * (BY_NAME[n]['blur']['K'] if BY_NAME[n]['blur'] else 1))
    with ProcessPoolExecutor(max(1, a.j)) as ex:
        res = list(ex.map(render_scene, [BY_NAME[n] for n in order]))
    print('rendered %d scenes in %.1f s' % (len(res), time.time() - t0))


if __name__ == '__main__':
    main()

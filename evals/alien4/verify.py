"""Self-checks of the renderer's conventions and of the truth files.

    python verify.py            # prints a report; exit 1 if a check fails

1. straight tubes (horizontal, and oblique at 23 deg), no noise/blur: the per-column
   centroid of |I - background| must sit on the true centreline (pixel centre = integer);
2. analytic anti-aliasing against brute force: a curved, self-crossing tube (round cap and
   flat cap) rendered at 8x resolution by point sampling and block-averaged must match the
   analytically prefiltered render;
3. every scene: truth centreline spacing, base/tip/length/bend consistent with the points,
   bend sign against the turning of the points, tube inside the frame, the rendered tube
   coverage ~1 along the truth centreline and ~0.5 at the truth tip (the tube's end),
   the holder's end at the truth base, and the written frames dark/bright where the truth
   says the tube is.
"""
import json
import math
import os
import sys

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import render as r  # noqa: E402
from preview import read_frames  # noqa: E402

FAIL = []
TWO = 2 * math.pi


def check(ok, msg):
    print(('  ok   ' if ok else '  FAIL ') + msg)
    if not ok:
        FAIL.append(msg)


def straight_image(look, angle_deg, R, W=260, H=300, base=(5.3, -150.37), cap='round',
                   sigma=0.0, length=240.0, back=300.0):
    sp = r.merged(dict(name='t', look=look, W=W, H=H, cap=cap, holder=dict(kind='none')))
    phi = math.radians(angle_deg)
    sh = r.Shape(base, phi, [length], [0.0], 0.0, R, cap, back, 48.0)
    prof = r.make_profiles(sp, R)
    F = r.tube_fields(sh, prof, sp, W, H, 1.0)
    info = r.look_info(sp, R)
    I = r.compose(sp, F, None, np.ones((H, W)), np.zeros((H, W)), 1.0, info)
    if sigma:
        I = r.psf(I, dict(kind='gauss', sigma=sigma))
    bgv = r.compose(sp, {k: np.zeros((3, 3)) for k in F}, None, np.ones((3, 3)),
                    np.zeros((3, 3)), 1.0, info)[1, 1]
    return I, bgv, sh


LOOKS = ('brightfield', 'bright_lumen', 'phase', 'dic', 'fluorescent', 'opaque')


def test_symmetry():
    print('1a. a long straight tube through a pixel centre (or a pixel corner), any angle, '
          'any look: the image must be point-symmetric about that point (rotation by 180 deg '
          'maps the pixel grid and the tube onto themselves; DIC is antisymmetric)')
    W = H = 161
    for look in LOOKS:
        for ang in (0.0, 17.0, 45.0, 73.3, -31.0):
            for centre in ((80.0, 80.0), (80.5, 80.5)):
                R = 7.3
                phi = math.radians(ang)
                L = 400.0
                cx, cy = centre
                base = (cx - L / 2 * math.cos(phi), -cy - L / 2 * math.sin(phi))
                I, bgv, sh = straight_image(look, ang, R, W=W + (1 if cx % 1 else 0),
                                            H=H + (1 if cy % 1 else 0), base=base, cap='flat',
                                            length=L, back=10.0)
                if look == 'dic':
                    # DIC = bg*(1 + gain*d/d(shear) OPL - 0.05*OPL): take the OPL's symmetry
                    # and check that the relief is antisymmetric once the OPL term is removed
                    sp = r.merged(dict(name='t', look='dic', W=I.shape[1], H=I.shape[0],
                                       cap='flat', holder=dict(kind='none')))
                    phi = math.radians(ang)
                    sh2 = r.Shape(base, phi, [L], [0.0], 0.0, R, 'flat', 10.0, 48.0)
                    F = r.tube_fields(sh2, r.make_profiles(sp, R), sp, I.shape[1], I.shape[0],
                                      1.0)
                    rel = I - bgv * (1 - 0.05 * F['solid'])
                    d = max(np.abs(F['solid'] - F['solid'][::-1, ::-1]).max(),
                            np.abs(rel + rel[::-1, ::-1]).max())
                else:
                    d = np.abs(I - I[::-1, ::-1]).max()
                check(d < 1e-6, '%-12s angle %6.1f about (%.1f,%.1f): max |I - rot180(I)| '
                      '%.1e' % (look, ang, cx, cy, d))


def test_straight():
    print('1b. straight tube at a sub-pixel offset (row 150.37), no noise, 0.9 px PSF: '
          'per-column centroid of |I - background| (looks whose |I - bg| is one-signed) '
          'against the true centreline')
    for look in ('brightfield', 'fluorescent', 'opaque'):
        for ang in (0.0, 23.0, -8.0):
            for R in (4.0, 11.3):
                I, bgv, sh = straight_image(look, ang, R, sigma=0.9)
                errs = []
                for c in range(60, 180):
                    yc = sh.base[1] + (c - sh.base[0]) * math.tan(math.radians(ang))
                    rc = -yc
                    half = int((R + 4) / math.cos(math.radians(ang))) + 2
                    rows = np.arange(int(rc) - half, int(rc) + half + 2)
                    w = np.abs(I[rows, c] - bgv)
                    errs.append((w * rows).sum() / w.sum() - rc)
                errs = np.array(errs)
                check(abs(errs.mean()) < 0.02 and np.abs(errs).max() < 0.02,
                      '%-12s angle %5.1f R %4.1f: mean %+.4f px, max |%.4f| px'
                      % (look, ang, R, errs.mean(), np.abs(errs).max()))


def brute_vs_analytic():
    S = 20
    print('2. analytic anti-aliasing against %dx%d brute-force point super-sampling of a '
          'curved, self-crossing 2-section tube (400 deg)' % (S, S))
    W, H = 110, 100
    for cap in ('round', 'flat'):
        R = 5.6
        base = (15.25, -70.6)
        lens = [80.0, 60.0]
        total = math.radians(400)
        kap = np.array([1.3, 0.8])
        kap = total * kap / (kap * np.array(lens)).sum()
        tail = 0.0
        sp = r.merged(dict(name='t', look='brightfield', W=W, H=H, cap=cap,
                           holder=dict(kind='none')))
        sh = r.Shape(base, 0.1, lens, kap, tail, R, cap, 300.0, 48.0)
        F = r.tube_fields(sh, r.make_profiles(sp, R), sp, W, H, 1.0)
        # hi-res pixel (C,Rr) centre <-> low-res ((C+0.5)/S-0.5, (Rr+0.5)/S-0.5)
        bh = ((base[0] + 0.5) * S - 0.5, -((-base[1] + 0.5) * S - 0.5))
        shh = r.Shape(bh, 0.1, [l * S for l in lens], kap / S, tail * S, R * S, cap,
                      300.0 * S, 48.0 * S)
        sph = dict(sp, W=W * S, H=H * S)
        Fh = r.tube_fields(shh, r.make_profiles(sph, R * S, box=0.0), sph, W * S, H * S, 1.0)
        Fh['T'] = np.exp(Fh['logT'])
        F['T'] = np.exp(F['logT'])
        from scipy.ndimage import binary_dilation
        crossing = binary_dilation(F['cov'] > 1.0 + 1e-6)
        for key in ('cov', 'solid', 'rim', 'lumen', 'T'):
            lo = F[key]
            hi = Fh[key].reshape(H, S, W, S).mean(axis=(1, 3))
            d = np.abs(lo - hi)
            if key != 'T':
                # (the lumen's end inside the solid cap is a 1-px ramp: allow a little more)
                check(d.max() < (0.05 if key == 'lumen' else 0.03) and d.mean() < 5e-4,
                      'cap %-5s %-6s: max |analytic - brute| %.4f, mean %.5f (field peak %.2f)'
                      % (cap, key, d.max(), d.mean(), hi.max()))
            else:
                check(d[~crossing].max() < 0.02 and d.mean() < 5e-4,
                      'cap %-5s transmission: max |analytic - brute| %.4f away from the '
                      'crossing, %.4f on its %d pixels (two layers multiplied per pixel), '
                      'mean %.5f (tube contrast %.2f)' % (cap, d[~crossing].max(),
                                                          d[crossing].max(), crossing.sum(),
                                                          d.mean(), np.abs(1 - hi).max()))
        cc, rr = np.meshgrid(np.arange(W), np.arange(H))
        hi = Fh['cov'].reshape(H, S, W, S).mean(axis=(1, 3))
        dx = (F['cov'] * cc).sum() / F['cov'].sum() - (hi * cc).sum() / hi.sum()
        dy = (F['cov'] * rr).sum() / F['cov'].sum() - (hi * rr).sum() / hi.sum()
        check(abs(dx) < 0.005 and abs(dy) < 0.005,
              'cap %-5s: coverage centroid analytic - brute = (%+.4f, %+.4f) px' % (cap, dx, dy))
        check(abs(F['cov'].sum() - hi.sum()) / hi.sum() < 1e-3,
              'cap %-5s: total coverage analytic %.2f vs brute %.2f px^2 (layers add)'
              % (cap, F['cov'].sum(), hi.sum()))


def unwrap_turning(X, Y):
    a = np.arctan2(np.diff(Y), np.diff(X))
    return np.unwrap(a)


def scene_checks():
    print('3. per-scene truth checks')
    for spec in r.SCENES:
        name = spec['name']
        d = os.path.join(HERE, 'scenes', name)
        meta = json.load(open(os.path.join(d, 'scene.json')))
        um = meta['um_per_px']
        tr = np.genfromtxt(os.path.join(d, 'truth_tracks.csv'), delimiter=',', names=True,
                           dtype=None, encoding='utf-8')
        cl = np.loadtxt(os.path.join(d, 'truth_centrelines.csv'), delimiter=',', skiprows=1)
        sp = r.merged(spec)
        geo = r.build_geometry(sp)
        W, H = sp['W'], sp['H']
        problems = []
        frames = read_frames(d)
        if len(frames) != sp['n_frames']:
            problems.append('read %d frames, expected %d' % (len(frames), sp['n_frames']))
        prof = r.make_profiles(sp, geo['R'])
        worst = dict(bend=0, spacing=0, length=0, tipcov=0, margin=1e9, cov=1, contrast=1e9)
        for row in tr:
            k = int(row['frame'])
            c = cl[cl[:, 0] == k]
            X, Y = c[:, 2] / um, c[:, 3] / um
            col, rowp = X, -Y
            seg = np.hypot(np.diff(X), np.diff(Y))
            worst['spacing'] = max(worst['spacing'], seg.max())
            Lpoly = seg.sum()
            worst['length'] = max(worst['length'], abs(Lpoly - row['length_um'] / um))
            turn = unwrap_turning(X, Y)
            t0 = np.array([-3 * X[0] + 4 * X[1] - X[2], -3 * Y[0] + 4 * Y[1] - Y[2]])
            t1 = np.array([3 * X[-1] - 4 * X[-2] + X[-3], 3 * Y[-1] - 4 * Y[-2] + Y[-3]])
            a0 = math.atan2(t0[1], t0[0])
            a1 = math.atan2(t1[1], t1[0])
            d0 = (turn[0] - a0 + math.pi) % TWO - math.pi
            d1 = (a1 - turn[-1] + math.pi) % TWO - math.pi
            bend_pts = math.degrees(turn[-1] - turn[0] + d0 + d1)
            worst['bend'] = max(worst['bend'], abs(bend_pts - row['bend_angle_deg']))
            if abs(c[0, 2] - row['base_x_um']) > 1e-3 or abs(c[0, 3] - row['base_y_um']) > 1e-3 \
                    or abs(c[-1, 2] - row['tip_x_um']) > 1e-3 or abs(c[-1, 3] - row['tip_y_um']) > 1e-3:
                problems.append('frame %d: base/tip not the end points' % k)
            if abs(c[0, 1]) > 1e-6 or abs(c[-1, 1] - row['length_um']) > 1e-2:
                problems.append('frame %d: s range' % k)
            R = geo['R']
            if not sp['entry']:
                m = min(col.min() - R, W - 1 - (col.max() + R), rowp.min() - R,
                        H - 1 - (rowp.max() + R))
                worst['margin'] = min(worst['margin'], m)
            # rendered coverage along the truth
            if k in (0, len(tr) // 2, len(tr) - 1):
                sh = geo['shapes'][k]
                F = r.tube_fields(sh, prof, sp, W, H, 1.0)
                cov = F['cov']
                s = c[:, 1] / um
                inner = (s > 1.0) & (s < sh.L - R - 1.0)
                ci = np.clip(np.round(col[inner]).astype(int), 0, W - 1)
                ri = np.clip(np.round(rowp[inner]).astype(int), 0, H - 1)
                worst['cov'] = min(worst['cov'], cov[ri, ci].min())
                # bilinear coverage at the truth tip
                tx, ty = col[-1], rowp[-1]
                x0, y0 = int(math.floor(tx)), int(math.floor(ty))
                fx, fy = tx - x0, ty - y0
                tc = ((1 - fx) * (1 - fy) * cov[y0, x0] + fx * (1 - fy) * cov[y0, x0 + 1]
                      + (1 - fx) * fy * cov[y0 + 1, x0] + fx * fy * cov[y0 + 1, x0 + 1])
                worst['tipcov'] = max(worst['tipcov'], abs(tc - 0.5))
                # holder end at the base: holder coverage just behind / in front of the base
                if sp['holder']['kind'] != 'none':
                    Hf = r.holder_fields(sp, sh.base, sh.phi0, R, W, H)
                    t0 = np.array([math.cos(sh.phi0), -math.sin(sh.phi0)])
                    b = np.array([col[0], rowp[0]])
                    nrm = np.array([-t0[1], t0[0]])
                    vals = []
                    for off in (-2.0, 2.0):
                        p = b + off * t0 + 0.8 * R * nrm    # inside the pipette wall region
                        vals.append(Hf['cov'][int(round(p[1])), int(round(p[0]))])
                    if not (vals[0] > 0.99 and vals[1] < 0.01):
                        problems.append('frame %d: holder end not at base (%s)' % (k, vals))
                # written frame: tube visible where the truth says (smoothed frame; on the
                # line against the mean of the two sides 3R away, relative to side-vs-side)
                f = frames[k].astype(float)
                if f.ndim == 3:
                    f = f.mean(axis=2)
                sg = max(1.0, R / 3)
                raw = f
                f = cv2.GaussianBlur(f, (0, 0), sg)
                resid = raw - cv2.GaussianBlur(raw, (0, 0), 1.5)
                mad = 1.4826 * np.median(np.abs(resid - np.median(resid)))
                noise_s = mad / (2 * math.sqrt(math.pi) * sg) + 0.05
                ang = np.unwrap(np.arctan2(np.gradient(Y), np.gradient(X)))
                nx, ny = -np.sin(ang), -np.cos(ang)     # left normal in (col,row)
                sel = np.where(inner)[0][::3]

                def samp(cx, cy):
                    okk = (cx >= 0) & (cx <= W - 1) & (cy >= 0) & (cy <= H - 1)
                    v = np.full(cx.shape, np.nan)
                    v[okk] = f[np.round(cy[okk]).astype(int), np.round(cx[okk]).astype(int)]
                    return v
                on = samp(col[sel], rowp[sel])
                o1 = samp(col[sel] + 3 * R * nx[sel], rowp[sel] + 3 * R * ny[sel])
                o2 = samp(col[sel] - 3 * R * nx[sel], rowp[sel] - 3 * R * ny[sel])
                good = np.isfinite(o1) & np.isfinite(o2)
                sig = np.nanmedian(np.abs(on[good] - (o1[good] + o2[good]) / 2))
                worst['contrast'] = min(worst['contrast'], sig / noise_s)
        # bend sign: CCW in y-up = turning to the left; check on last frame
        last = tr[-1]
        sgn_ok = np.sign(last['bend_angle_deg']) == np.sign(sp['bend_deg'] or sp['bend_start_deg'])
        if not sgn_ok:
            problems.append('bend sign')
        if worst['bend'] > 0.05:
            problems.append('bend vs points %.3f deg' % worst['bend'])
        if worst['spacing'] > 1.0:
            problems.append('spacing %.2f px' % worst['spacing'])
        if worst['length'] > 0.01:
            problems.append('length vs polyline %.4f px' % worst['length'])
        if not sp['entry'] and worst['margin'] < 3:
            problems.append('tube within %.1f px of the border' % worst['margin'])
        if worst['cov'] < 0.99:
            problems.append('coverage along truth %.3f' % worst['cov'])
        if worst['tipcov'] > 0.1:
            problems.append('tip coverage off 0.5 by %.3f' % worst['tipcov'])
        if sp['look'] != 'dic' and worst['contrast'] < 3:
            problems.append('tube barely differs from off-tube (ratio %.2f)' % worst['contrast'])
        check(not problems, '%-26s bend-vs-points %.4f deg, spacing %.2f px, min margin %s px, '
              'cov on line %.3f, |tipcov-0.5| %.3f, SNR on line %.0f %s'
              % (name, worst['bend'], worst['spacing'],
                 '%.1f' % worst['margin'] if not sp['entry'] else 'border',
                 worst['cov'], worst['tipcov'], worst['contrast'], '; '.join(problems)))


def sign_demo():
    print('4. sign / axis conventions')
    sp = r.merged(dict(name='t'))
    sh = r.Shape((50.0, -100.0), 0.0, [100.0], [math.radians(90) / 100.0], 0.0, 5.0, 'flat',
                 100.0, 48.0)
    X, Y = sh.points(np.array([0.0, sh.L]))
    # base pointing +x (right), +90 deg CCW bend: tip must end up above (smaller row)
    check(-Y[1] < -Y[0] and abs(X[1] - (50 + 100 / (math.pi / 2))) < 1e-6,
          '+90 deg from a base pointing right ends up-right: tip (col %.3f,row %.3f), '
          'radius %.3f' % (X[1], -Y[1], 100 / (math.pi / 2)))
    F = r.tube_fields(sh, r.TubeProfiles(5.0, 0.6, 0.0), sp, 200, 200, 1.0)
    check(F['cov'][int(round(-Y[1])) + 2, int(round(X[1]))] > 0.9 and F['cov'][60, 150] < 0.01,
          'rendered pixels follow the same (col,row) geometry')


if __name__ == '__main__':
    sign_demo()
    test_symmetry()
    test_straight()
    brute_vs_analytic()
    scene_checks()
    print('%d checks failed' % len(FAIL))
    sys.exit(1 if FAIL else 0)

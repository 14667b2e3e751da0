#!/usr/bin/env python
"""Run a tube tracker on every scene of this evaluation set and score it against the truth.

    python score.py [--microtube PATH] [--only NAME ...] [-j 2] [--out RESULTS_DIR]

For each scene: ``PATH track <input> --out RESULTS_DIR/<name> --um-per-px <um_per_px> -q``
(timeout 300 s; a non-zero exit or a timeout is a failure, with its stderr's last line).
Per frame: angle error (measured - true, deg), centreline RMS distance (px) of the measured
points to the true polyline (point-to-segment), length error %, base and tip error (px).
A frame is lost when its bend angle is NaN or missing.
Per scene: pass = lost == 0 and median|angle err| <= 0.5 and p95 <= 2 and max <= 5 and
median RMS <= 0.5 px and max |length err| <= 1 %.
Writes RESULTS_DIR/summary.csv and RESULTS_DIR/per_frame.csv, prints a table.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = os.path.join(HERE, 'scenes')
DEFAULT_TRACKER = os.path.join(HERE, '..', '..', '.venv', 'bin', 'microtube')
TIMEOUT = 300


def polyline_distance(pts, poly):
    """Distance of each point in pts (N,2) to the polyline poly (M,2), point-to-segment."""
    if len(poly) < 2:
        return np.hypot(*(pts - poly[0]).T)
    a, b = poly[:-1], poly[1:]
    tree = cKDTree(poly)
    k = min(6, len(poly))
    _, nn = tree.query(pts, k=k)
    nn = np.atleast_2d(nn)
    if nn.shape[0] != len(pts):
        nn = nn.T
    best = np.full(len(pts), np.inf)
    for j in range(nn.shape[1]):
        for seg in (nn[:, j] - 1, nn[:, j]):
            seg = np.clip(seg, 0, len(a) - 1)
            A, B = a[seg], b[seg]
            AB = B - A
            L2 = np.maximum((AB ** 2).sum(1), 1e-12)
            t = np.clip(((pts - A) * AB).sum(1) / L2, 0, 1)
            P = A + t[:, None] * AB
            best = np.minimum(best, np.hypot(*(pts - P).T))
    return best


def run_tracker(tracker, name, meta, out_dir):
    inp = os.path.join(SCENES, name, meta['input'])
    cmd = [tracker, 'track', inp, '--out', out_dir, '--um-per-px', repr(meta['um_per_px']),
           '-q']
    t0 = time.time()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
        wall = time.time() - t0
        if p.returncode != 0:
            lines = [ln for ln in (p.stderr or '').strip().splitlines() if ln.strip()]
            return wall, 'exit %d: %s' % (p.returncode, lines[-1] if lines else '(no stderr)')
        return wall, None
    except subprocess.TimeoutExpired:
        return time.time() - t0, 'timeout after %d s' % TIMEOUT
    except OSError as e:
        return time.time() - t0, 'cannot run tracker: %s' % e


def score_scene(tracker, name, results):
    d = os.path.join(SCENES, name)
    meta = json.load(open(os.path.join(d, 'scene.json')))
    um = meta['um_per_px']
    out_dir = os.path.join(results, name)
    os.makedirs(out_dir, exist_ok=True)
    for stale in ('tracks.csv', 'centrelines.csv'):
        if os.path.exists(os.path.join(out_dir, stale)):
            os.remove(os.path.join(out_dir, stale))
    wall, err = run_tracker(tracker, name, meta, out_dir)
    truth = pd.read_csv(os.path.join(d, 'truth_tracks.csv'))
    tcl = pd.read_csv(os.path.join(d, 'truth_centrelines.csv'))
    rows = []
    meas = mcl = None
    if err is None:
        try:
            meas = pd.read_csv(os.path.join(out_dir, 'tracks.csv'))
            mcl = pd.read_csv(os.path.join(out_dir, 'centrelines.csv'))
        except Exception as e:  # noqa: BLE001
            err = 'unreadable output: %s' % e
    tgroups = {f: g for f, g in tcl.groupby('frame')}
    mgroups = {f: g for f, g in mcl.groupby('frame')} if mcl is not None else {}
    mrow = {int(r.frame): r for r in meas.itertuples()} if meas is not None else {}
    for t in truth.itertuples():
        f = int(t.frame)
        rec = dict(scene=name, frame=f, true_bend_deg=t.bend_angle_deg, meas_bend_deg=np.nan,
                   angle_err_deg=np.nan, rms_px=np.nan, length_err_pct=np.nan,
                   base_err_px=np.nan, tip_err_px=np.nan, lost=True, status='')
        m = mrow.get(f)
        if m is not None:
            rec['status'] = str(getattr(m, 'status', ''))
            bend = float(m.bend_angle_deg) if m.bend_angle_deg == m.bend_angle_deg else np.nan
            rec['meas_bend_deg'] = bend
            if np.isfinite(bend):
                rec['lost'] = False
                rec['angle_err_deg'] = bend - t.bend_angle_deg
                rec['length_err_pct'] = (float(m.length_um) - t.length_um) / t.length_um * 100
                rec['base_err_px'] = math.hypot(float(m.base_x_um) - t.base_x_um,
                                                float(m.base_y_um) - t.base_y_um) / um
                rec['tip_err_px'] = math.hypot(float(m.tip_x_um) - t.tip_x_um,
                                               float(m.tip_y_um) - t.tip_y_um) / um
                g = mgroups.get(f)
                if g is not None and len(g):
                    tg = tgroups[f]
                    poly = np.stack([tg.x_um.values, tg.y_um.values], 1) / um
                    pts = np.stack([g.x_um.values, g.y_um.values], 1) / um
                    pts = pts[np.isfinite(pts).all(1)]
                    if len(pts):
                        dist = polyline_distance(pts, poly)
                        rec['rms_px'] = float(np.sqrt((dist ** 2).mean()))
        rows.append(rec)
    pf = pd.DataFrame(rows)
    ok = pf[~pf.lost]
    ae = ok.angle_err_deg.abs()
    s = dict(scene=name, frames=len(pf), lost=int(pf.lost.sum()),
             med_angle=ae.median() if len(ok) else np.nan,
             p95_angle=ae.quantile(0.95) if len(ok) else np.nan,
             max_angle=ae.max() if len(ok) else np.nan,
             med_rms_px=ok.rms_px.median() if len(ok) else np.nan,
             max_len_pct=ok.length_err_pct.abs().max() if len(ok) else np.nan,
             med_base_px=ok.base_err_px.median() if len(ok) else np.nan,
             med_tip_px=ok.tip_err_px.median() if len(ok) else np.nan,
             wall_s=round(wall, 1), error=err or '')
    s['pass'] = bool(err is None and s['lost'] == 0 and s['med_angle'] <= 0.5
                     and s['p95_angle'] <= 2 and s['max_angle'] <= 5
                     and s['med_rms_px'] <= 0.5 and s['max_len_pct'] <= 1.0)
    print('  done %-26s %s %5.1fs%s' % (name, 'PASS' if s['pass'] else 'fail', wall,
                                        ('  ' + err) if err else ''), flush=True)
    return s, pf


def fmt(v, nd=2):
    if isinstance(v, float):
        return 'nan' if not np.isfinite(v) else ('%.*f' % (nd, v))
    return str(v)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--microtube', default=DEFAULT_TRACKER)
    ap.add_argument('--only', nargs='*')
    ap.add_argument('-j', type=int, default=1)
    ap.add_argument('--out', default=os.path.join(HERE, 'results'))
    a = ap.parse_args(argv)
    names = sorted(n for n in os.listdir(SCENES)
                   if os.path.exists(os.path.join(SCENES, n, 'scene.json')))
    if a.only:
        missing = set(a.only) - set(names)
        if missing:
            sys.exit('unknown scene(s): ' + ', '.join(sorted(missing)))
        names = [n for n in names if n in a.only]
    os.makedirs(a.out, exist_ok=True)
    t0 = time.time()
    with ThreadPoolExecutor(max(1, a.j)) as ex:
        res = list(ex.map(lambda n: score_scene(a.microtube, n, a.out), names))
    summ = pd.DataFrame([r[0] for r in res])
    per = pd.concat([r[1] for r in res], ignore_index=True)
    summ.to_csv(os.path.join(a.out, 'summary.csv'), index=False)
    per.to_csv(os.path.join(a.out, 'per_frame.csv'), index=False)
    head = ('%-26s %6s %4s %9s %9s %9s %8s %8s %8s %7s %5s'
            % ('scene', 'frames', 'lost', 'med|dA|', 'p95|dA|', 'max|dA|', 'rms px', 'max|dL|%',
               'base px', 'wall s', 'pass'))
    print()
    print(head)
    print('-' * len(head))
    for r in summ.to_dict('records'):
        print('%-26s %6d %4d %9s %9s %9s %8s %8s %8s %7.1f %5s%s'
              % (r['scene'], r['frames'], r['lost'], fmt(r['med_angle']),
                 fmt(r['p95_angle']), fmt(r['max_angle']), fmt(r['med_rms_px']),
                 fmt(r['max_len_pct']), fmt(r['med_base_px']), r['wall_s'],
                 'yes' if r['pass'] else 'no', ('  [' + r['error'] + ']') if r['error'] else ''))
    print('-' * len(head))
    print('%d/%d pass, frames lost %d   (%.0f s)' % (summ['pass'].sum(), len(summ),
                                                      summ['lost'].sum(), time.time() - t0))


if __name__ == '__main__':
    main()

"""Contact sheet of the first, middle and last frame of each scene (for eyeballing)."""
import glob, json, os, sys
import cv2, numpy as np, tifffile

HERE = os.path.dirname(os.path.abspath(__file__))


def read_frames(d):
    m = json.load(open(os.path.join(d, 'scene.json')))
    p = os.path.join(d, m['input'])
    if os.path.isdir(p):
        return [cv2.imread(f, cv2.IMREAD_UNCHANGED) for f in sorted(glob.glob(p + '/*'))]
    if p.endswith('.tif'):
        return list(tifffile.imread(p))
    c = cv2.VideoCapture(p)
    out = []
    while True:
        ok, f = c.read()
        if not ok:
            break
        out.append(f)
    return out


def to8(f):
    if f.dtype == np.uint16:
        f = (f.astype(float) / max(1, f.max()) * 255).astype(np.uint8)
    if f.ndim == 2:
        f = cv2.cvtColor(f, cv2.COLOR_GRAY2BGR)
    elif f.shape[2] == 3 and f.dtype == np.uint8:
        pass
    return f


if __name__ == '__main__':
    out = sys.argv[1]
    names = sys.argv[2:] or sorted(os.listdir(os.path.join(HERE, 'scenes')))
    os.makedirs(out, exist_ok=True)
    for name in names:
        d = os.path.join(HERE, 'scenes', name)
        fr = read_frames(d)
        sel = [to8(fr[0]), to8(fr[len(fr) // 2]), to8(fr[-1])]
        h = 260
        sel = [cv2.resize(f, (int(f.shape[1] * h / f.shape[0]), h), interpolation=cv2.INTER_AREA)
               for f in sel]
        cv2.imwrite(os.path.join(out, name + '.png'), np.hstack(sel))

"""Reading and writing frame sequences: videos, image folders, multi-page TIFFs.

Frames are streamed one at a time (memory stays flat in the number of frames)
as 2-D greyscale arrays in their native dtype (uint8, uint16 or float32).
Colour input is converted to grey by luminance, or taken from one channel
alone (``open_frames(channel=...)``: :mod:`pipeline.colour` says which).
Every problem with the input raises :class:`FrameError` with one line naming
the file and what is wrong.

Writers (:func:`write_frames`) are atomic: the output appears complete or not
at all, whatever happens to the frame iterable midway.
"""

from __future__ import annotations

import json
import os
import re
import weakref
from collections.abc import Iterable, Iterator
from pathlib import Path

import cv2
import numpy as np

from .atomic import atomic_dir, atomic_path

# FFmpeg, under OpenCV's video IO, prints its own complaints to stderr (e.g.
# "[mjpeg @ 0x…] overread 8" on a truncated file), where they would break the
# command line's one-line messages: the reader reports what it cannot decode
# itself. OpenCV reads this once, when its FFmpeg backend first starts, so it
# is set on import; a value the user has set is kept.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg", ".bmp", ".webp", ".jp2",
                  ".pgm", ".ppm", ".pnm")
TIFF_SUFFIXES = (".tif", ".tiff")
VIDEO_SUFFIXES = (".avi", ".mp4", ".mov", ".mkv", ".m4v", ".mpg", ".mpeg", ".wmv", ".webm",
                  ".flv", ".ogv", ".mjpeg", ".mjpg", ".gif")
WRITE_VIDEO_FOURCC = {".avi": "MJPG", ".mp4": "mp4v"}
FRAME_NAME = "frame_{:05d}.png"
_FRAME_NAME_RE = re.compile(r"frame_\d{5,}\.png")

# IMREAD_UNCHANGED keeps 16-bit depth and the alpha channel; EXIF rotation is
# deliberately not applied, so frames match the sensor's pixel grid.
_IMREAD_FLAGS = cv2.IMREAD_UNCHANGED


class FrameError(ValueError):
    """Unreadable, missing or inconsistent frame input (or unwritable output)."""


# --------------------------------------------------------------------------- helpers

def _natural_key(path: Path):
    """Sort key under which ``frame2`` comes before ``frame10``."""
    return [(0, int(t), "") if t.isdigit() else (1, 0, t.lower())
            for t in re.split(r"(\d+)", path.name)]


#: The colour channels :func:`open_frames` can take alone instead of the
#: luminance, and their places in an RGB image.
CHANNELS = {"red": 0, "green": 1, "blue": 2}


def _to_grey(img: np.ndarray, where: str, *, rgb: bool = False,
             channel: str | None = None) -> np.ndarray:
    """2-D grey frame from a grey, grey+alpha, BGR(A) or (``rgb=True``) RGB(A)
    image: the luminance, or a colour image's ``channel`` alone (a name of
    :data:`CHANNELS`)."""
    if img.ndim == 2:
        return img
    if img.ndim != 3 or img.shape[2] not in (1, 2, 3, 4):
        raise FrameError(f"{where}: unsupported image layout {img.shape} "
                         "(expected rows x cols, optionally x 1-4 channels)")
    channels = img.shape[2]
    if channels <= 2:  # grey, or grey + alpha: the alpha carries no brightness
        return np.ascontiguousarray(img[:, :, 0])
    if img.dtype not in (np.uint8, np.uint16, np.float32):
        img = img.astype(np.float32)
    if channel is not None:
        k = CHANNELS[channel]
        return np.ascontiguousarray(img[:, :, k if rgb else 2 - k])
    if rgb:
        code = cv2.COLOR_RGB2GRAY if channels == 3 else cv2.COLOR_RGBA2GRAY
    else:
        code = cv2.COLOR_BGR2GRAY if channels == 3 else cv2.COLOR_BGRA2GRAY
    return cv2.cvtColor(img, code)


def _native_dtype(img: np.ndarray, where: str) -> np.ndarray:
    """uint8/uint16 as they are; floats as float32; other integers as uint16 if they fit."""
    if img.dtype in (np.uint8, np.uint16):
        return img
    if img.dtype == bool:
        return img.astype(np.uint8) * np.uint8(255)
    if np.issubdtype(img.dtype, np.floating):
        if not np.all(np.isfinite(img)):
            raise FrameError(f"{where}: image holds NaN or infinite values")
        return img.astype(np.float32, copy=False)
    if np.issubdtype(img.dtype, np.integer):
        # silently clipping e.g. int16 or 32-bit counts would corrupt intensities
        lo, hi = int(img.min()), int(img.max())
        if lo < 0 or hi > 65535:
            raise FrameError(f"{where}: {img.dtype} pixel values {lo}..{hi} do not fit 0..65535")
        return img.astype(np.uint16)
    raise FrameError(f"{where}: unsupported pixel type {img.dtype}")


def _tiff_page(page, where: str, channel: str | None = None, *,
               grey: bool = True) -> np.ndarray:
    """One TIFF page as a native-dtype grey frame (``channel``: see
    :func:`_to_grey`); with ``grey=False``, as it is stored, its samples last."""
    try:
        img = page.asarray()
    except Exception as exc:  # tifffile raises many types on corrupt data
        raise FrameError(f"{where}: unreadable TIFF page ({type(exc).__name__}: "
                         f"{_one_line(exc)})") from None
    if img.ndim == 3 and getattr(page, "axes", "").startswith("S"):
        img = np.moveaxis(img, 0, -1)  # planar (separate) samples -> channels last
    if not grey:
        return img
    return _native_dtype(_to_grey(img, where, rgb=True, channel=channel), where)


def _read_image(path: Path, where: str, channel: str | None = None) -> np.ndarray:
    """A single image file as a native-dtype grey frame (first page of a TIFF;
    ``channel``: see :func:`_to_grey`)."""
    if path.suffix.lower() in TIFF_SUFFIXES:
        import tifffile

        try:
            with tifffile.TiffFile(path) as tif:
                if not len(tif.pages):
                    raise FrameError(f"{where}: the TIFF holds no pages")
                return _tiff_page(tif.pages[0], where, channel)
        except FrameError:
            raise
        except Exception as exc:
            raise FrameError(f"{where}: not a readable TIFF ({type(exc).__name__})") from None
    img = _imread(path)
    if img is None:
        size = _size(path)
        why = "empty file (0 bytes)" if size == 0 else "not a readable image"
        raise FrameError(f"{where}: {why}")
    return _native_dtype(_to_grey(img, where, channel=channel), where)


def _imread(path: Path) -> np.ndarray | None:
    """``cv2.imread`` of ``path`` as stored (depth and channels), or None where
    it cannot be read (OpenCV reports that by returning None, or raising).
    OpenCV's own log is silenced meanwhile: it prints a damaged file's decoder
    error ("[ERROR:0@0.6] ... readHeader IHDR chunk shall be first") on stderr,
    before the command line's one-line message."""
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        return cv2.imread(str(path), _IMREAD_FLAGS)
    except cv2.error:
        return None
    finally:
        cv2.utils.logging.setLogLevel(level)


def _size(path: Path) -> int | None:
    try:
        return path.stat().st_size
    except OSError:
        return None


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:200]


def _tiff_fps(tif) -> float | None:
    """Frame rate from ImageJ (``fps``/``finterval``) or our own JSON description."""
    meta = {}
    try:
        if tif.is_imagej and tif.imagej_metadata:
            meta = dict(tif.imagej_metadata)
            if "fps" not in meta and meta.get("finterval"):
                meta["fps"] = 1.0 / float(meta["finterval"])
        elif tif.pages[0].description.lstrip().startswith("{"):
            meta = json.loads(tif.pages[0].description)
    except (ValueError, TypeError, ZeroDivisionError, KeyError):
        return None  # metadata is a bonus: a malformed tag must not stop reading
    return _valid_fps(meta.get("fps") if isinstance(meta, dict) else None)


def _valid_fps(value) -> float | None:
    try:
        fps = float(value)
    except (TypeError, ValueError):
        return None
    return fps if np.isfinite(fps) and 0 < fps < 1e6 else None


# --------------------------------------------------------------------------- reading

class FrameReader:
    """An iterable of 2-D greyscale frames; make one with :func:`open_frames`.

    Frames are decoded one at a time while iterating. Every ``iter(reader)``
    starts again from the first frame (the file is re-opened), so a reader can
    be iterated any number of times. Using the reader as a context manager
    closes any iteration still in progress on exit.

    Attributes
    ----------
    source : Path
        The file or folder that was opened.
    kind : {"video", "folder", "tiff", "image"}
    fps : float or None
        Frame rate when the source records one (videos; ImageJ or
        :func:`write_frames` TIFFs), else None.
    frame_shape : tuple of int
        ``(rows, cols)`` of the first frame.
    dtype : numpy.dtype
        Pixel type of the first frame: uint8, uint16 or float32.
    first : ndarray
        The first frame, as iterating yields it, decoded once on opening
        (read-only): a run looks at it several times before it tracks, and a
        video re-opened and decoded for each look cost up to 90 ms each
        (1024x768 FFV1).
    channel : str or None
        The colour channel a colour source's frames are taken from (a name of
        :data:`CHANNELS`); None: their luminance.
    first_jpeg : ndarray or None
        A Motion-JPEG video's first frame as stored (its bytes), where it was
        decoded from them: :func:`first_colour` decodes it again in colour.
    """

    def __init__(self, source: Path, kind: str, count: int, fps: float | None,
                 first: np.ndarray, files: list[Path] | None = None,
                 channel: str | None = None, first_jpeg: np.ndarray | None = None):
        self.source = source
        self.kind = kind
        self.fps = fps
        self.channel = channel
        self.frame_shape = tuple(first.shape)
        self.dtype = first.dtype
        self.first = first
        first.flags.writeable = False
        self._count = count
        self._files = files
        self._live = weakref.WeakSet()
        self.first_jpeg = first_jpeg

    def __len__(self) -> int:
        """Number of frames; for videos the container's count (best effort)."""
        return self._count

    def __repr__(self) -> str:
        return (f"FrameReader({str(self.source)!r}, kind={self.kind!r}, frames={self._count}, "
                f"shape={self.frame_shape}, dtype={self.dtype}, fps={self.fps})")

    def __enter__(self) -> FrameReader:
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False

    def close(self) -> None:
        """Stop iterations in progress, releasing their open files."""
        for gen in list(self._live):
            gen.close()

    def __iter__(self) -> Iterator[np.ndarray]:
        if self.kind == "video":
            gen = self._iter_video()
        elif self.kind == "tiff":
            gen = self._iter_tiff()
        else:
            gen = self._iter_files()
        self._live.add(gen)
        return gen

    def _check(self, img: np.ndarray, where: str) -> np.ndarray:
        if img.shape != self.frame_shape:
            raise FrameError(f"{where}: frame is {img.shape[0]}x{img.shape[1]} (rows x cols), "
                             f"the first is {self.frame_shape[0]}x{self.frame_shape[1]}")
        if img.dtype != self.dtype:
            raise FrameError(f"{where}: pixels are {img.dtype}, the first frame's are "
                             f"{self.dtype}")
        return img

    def _iter_files(self) -> Iterator[np.ndarray]:
        n = len(self._files)
        for i, path in enumerate(self._files):
            where = f"{path} (image {i} of {n})" if self.kind == "folder" else str(path)
            yield self._check(_read_image(path, where, self.channel), where)

    def _iter_tiff(self) -> Iterator[np.ndarray]:
        import tifffile

        try:
            tif = tifffile.TiffFile(self.source)
        except Exception as exc:
            raise FrameError(f"{self.source}: not a readable TIFF ({type(exc).__name__})") \
                from None
        with tif:
            # iterating TiffPages with its cache off keeps no decoded page alive
            tif.pages.cache = False
            for i, page in enumerate(tif.pages):
                where = f"{self.source} (page {i})"
                yield self._check(_tiff_page(page, where, self.channel), where)

    def _iter_video(self) -> Iterator[np.ndarray]:
        i = -1
        for i, grey in enumerate(_video_frames(self.source, channel=self.channel)):
            yield self._check(grey, f"{self.source} (frame {i})")
        if i < 0:
            raise FrameError(f"{self.source}: no frames could be decoded")


def require_source(source) -> Path:
    """``source`` as a Path, or :class:`FrameError` naming it if it does not exist."""
    path = Path(source)
    if not path.exists():
        raise FrameError(f"{path}: no such file or folder")
    return path


def open_frames(source, channel: str | None = None) -> FrameReader:
    """Open a video, a folder of images, a multi-page TIFF or a single image.

    Only the first frame is decoded here (for ``frame_shape`` and ``dtype``);
    the rest are decoded lazily while iterating, so a later unreadable or
    mis-shaped frame raises :class:`FrameError` from the iteration.

    Parameters
    ----------
    source : str or Path
        A video OpenCV can read (.avi, .mp4, .mov, .mkv, ...); a folder of
        PNG/TIFF/JPEG/BMP images, taken in natural name order (``frame2``
        before ``frame10``; other files and hidden files are ignored); a TIFF
        with one or more pages (read page by page; a hyperstack with
        channels or z-slices at every time point is refused); or one image file.
    channel : {"red", "green", "blue"}, optional
        Take a colour source's frames from this channel alone (grey ones as
        they are); default: their luminance.

    Returns
    -------
    FrameReader
        Iterable of (rows, cols) frames in their native dtype (uint8, uint16
        or float32), with ``len``, ``fps``, ``frame_shape``, ``dtype`` and
        ``source``; also a context manager.

    Raises
    ------
    FrameError
        Missing, empty, unsupported, unreadable or inconsistent input.
    """
    path = require_source(source)
    if channel is not None and channel not in CHANNELS:
        raise FrameError(f"unknown colour channel {channel!r} (one of {', '.join(CHANNELS)})")
    try:
        if path.is_dir():
            return _open_folder(path, channel)
        if path.stat().st_size == 0:
            raise FrameError(f"{path}: empty file (0 bytes)")
    except OSError as exc:
        raise FrameError(f"{path}: cannot be read ({_one_line(exc)})") from None
    suffix = path.suffix.lower()
    if suffix in TIFF_SUFFIXES:
        return _open_tiff(path, channel)
    if suffix in IMAGE_SUFFIXES:
        return FrameReader(path, "image", 1, None, _read_image(path, str(path), channel),
                           [path], channel)
    if suffix in VIDEO_SUFFIXES:
        return _open_video(path, channel)
    raise FrameError(f"{path}: unsupported file type {suffix or '(no suffix)'}: give a video "
                     f"({', '.join(VIDEO_SUFFIXES[:4])}, ...), an image, a TIFF stack or a "
                     "folder of images")


def _open_folder(path: Path, channel: str | None = None) -> FrameReader:
    files = sorted((p for p in path.iterdir()
                    if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".")
                    and p.is_file()), key=_natural_key)
    if not files:
        raise FrameError(f"{path}: the folder holds no images "
                         f"({', '.join(IMAGE_SUFFIXES)})")
    first = _read_image(files[0], f"{files[0]} (image 0 of {len(files)})", channel)
    return FrameReader(path, "folder", len(files), None, first, files, channel)


def _open_tiff(path: Path, channel: str | None = None) -> FrameReader:
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            count = len(tif.pages)  # walks the page directory only, no pixel data
            if not count:
                raise FrameError(f"{path}: no frames (the TIFF holds no pages)")
            _refuse_hyperstack(tif, path)
            first = _tiff_page(tif.pages[0], f"{path} (page 0)", channel)
            fps = _tiff_fps(tif)
    except FrameError:
        raise
    except Exception as exc:  # tifffile raises many types on corrupt files
        raise FrameError(f"{path}: not a readable TIFF ({type(exc).__name__}: "
                         f"{_one_line(exc)})") from None
    return FrameReader(path, "tiff", count, fps, first, channel=channel)


def first_colour(reader: FrameReader) -> np.ndarray | None:
    """The reader's first frame in colour.

    Parameters
    ----------
    reader : FrameReader

    Returns
    -------
    (rows, cols, 3) ndarray or None
        RGB, in the frame's native dtype (uint8, uint16 or float32); None
        where the source is grey, also a grey image stored as colour: its
        channels, each less its median, equal within 2 % of their range at
        99 % of the pixels (on every 4th row and column), as a grey video
        coded in colour decodes (an MPEG-4 one's channels 3 levels apart).
        (A colour tube on a background clipped white in every channel, under
        1 % of the frame, passes for grey too: it is tracked in the
        luminance, as before channels were looked at.)
    """
    where = f"{reader.source} (first frame)"
    try:
        if reader.kind == "video" and reader.first_jpeg is not None:
            # (decoded again from its bytes: re-opening the video cost 13 ms)
            null = os.open(os.devnull, os.O_WRONLY)
            try:
                img = _quiet_imdecode(reader.first_jpeg, null,
                                      cv2.IMREAD_COLOR | cv2.IMREAD_IGNORE_ORIENTATION)
            finally:
                os.close(null)
            rgb = False
        elif reader.kind == "video":
            cap = cv2.VideoCapture(str(reader.source))
            try:
                ok, img = cap.read()
            finally:
                cap.release()
            img = img if ok else None
            rgb = False
        elif reader.kind == "tiff" or reader._files[0].suffix.lower() in TIFF_SUFFIXES:
            import tifffile

            with tifffile.TiffFile(reader._files[0] if reader._files else reader.source) as tif:
                img = _tiff_page(tif.pages[0], where, grey=False)
            rgb = True
        else:
            img = _imread(reader._files[0])
            rgb = False
    except (cv2.error, OSError, ValueError):
        return None
    if img is None or img.ndim != 3 or img.shape[2] < 3 or img.shape[:2] != reader.frame_shape:
        return None
    img = img[:, :, :3] if rgb else img[:, :, 2::-1]
    if img.dtype not in (np.uint8, np.uint16, np.float32):
        # (as the luminance is made of them: int16 or 32-bit counts as float)
        img = img.astype(np.float32)
    # (on every 4th row and column: a whole frame's statistics cost 0.2 s)
    some = img[::4, ::4]
    span = float(np.ptp(some)) or 1.0
    centred = some.reshape(-1, 3).astype(np.float32)
    centred -= np.median(centred, axis=0)
    if np.percentile(np.abs(np.diff(centred, axis=1)).max(axis=1), 99) <= 0.02 * span:
        return None
    try:
        return _native_dtype(np.ascontiguousarray(img), where)
    except FrameError:
        return None


def _refuse_hyperstack(tif, path: Path) -> None:
    """Refuse a stack whose pages are not all frames: a hyperstack (ImageJ or
    OME, e.g. axes TCYX) with channels or z-slices at every time point has its
    pages alternate between them, and tracking them in turn would mix unrelated
    images. A stack along one axis is taken as frames, whatever its label:
    ImageJ saves a time-lapse as slices unless told otherwise, and tifffile
    labels a plain stack as channels."""
    if not (tif.is_imagej or tif.is_ome):
        # (only these label their axes; parsing another writer's series metadata
        # can make tifffile log a warning about it)
        return
    series = tif.series[0] if tif.series else None
    sizes = dict(zip(getattr(series, "axes", ""), getattr(series, "shape", ()), strict=False))
    stacked = {a: n for a, n in sizes.items() if a not in "YXS" and n > 1}
    if len(stacked) > 1:
        what = " x ".join(f"{n} {_AXIS_NAMES.get(a, a)}" for a, n in stacked.items())
        raise FrameError(f"{path}: a hyperstack ({what}): save one image of the tube per "
                         "time point as its own stack")


_AXIS_NAMES = {"T": "times", "C": "channels", "Z": "z-slices", "Q": "images", "I": "images"}


def _open_video(path: Path, channel: str | None = None) -> FrameReader:
    meta = {}
    frames = _video_frames(path, meta, channel=channel)
    try:
        first = next(frames, None)
    finally:
        frames.close()
    if first is None:
        raise FrameError(f"{path}: no frames (the video opens but its first frame cannot "
                         "be decoded)")
    return FrameReader(path, "video", meta["count"], meta["fps"], first, channel=channel,
                       first_jpeg=meta.get("first_jpeg"))


_MJPG = cv2.VideoWriter_fourcc(*"MJPG")
# EXIF orientation is ignored, as FFmpeg ignores it: frames keep the sensor's grid
_JPEG_GREY = cv2.IMREAD_GRAYSCALE | cv2.IMREAD_IGNORE_ORIENTATION


def _quiet_imdecode(data: np.ndarray, null: int, flags: int = _JPEG_GREY
                    ) -> np.ndarray | None:
    """``cv2.imdecode(data, flags)`` with the process's stderr pointed at
    ``null`` (an open file descriptor of os.devnull) meanwhile: libjpeg prints
    its warnings on a damaged frame ("Corrupt JPEG data: ...") straight to it,
    where they would break the command line's one-line messages (as FFmpeg's
    would, see OPENCV_FFMPEG_LOGLEVEL above); the frame is decoded all the
    same, and a frame too damaged to track says so in its row's status."""
    saved = os.dup(2)
    try:
        os.dup2(null, 2)
        return cv2.imdecode(data, flags)
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _video_frames(path: Path, meta: dict | None = None, *,
                  channel: str | None = None) -> Iterator[np.ndarray]:
    """Grey frames of a video, decoded one at a time; on opening, ``meta`` (if
    given) gets the container's ``count`` (>= 1, best effort) and ``fps``;
    ``channel``: see :func:`_to_grey`.

    Motion-JPEG frames are decoded straight to grey from their compressed
    bytes: a JPEG holds luminance as a channel of its own, with the weights of
    ``COLOR_BGR2GRAY``, so the chroma need not be decoded nor converted (about
    twice as fast as decoding colour). From the first frame the JPEG decoder
    refuses, or that comes out another size than the stream's (interlaced
    fields, say), the rest go through OpenCV's own decoding.
    """
    cap = null = None
    try:
        cap = cv2.VideoCapture(str(path))
        if not cap.isOpened():
            raise FrameError(f"{path}: not a readable video (corrupt, or a codec this OpenCV "
                             "lacks)")
        if meta is not None:
            count = cap.get(cv2.CAP_PROP_FRAME_COUNT)
            # containers may report -1, 0 or NaN frames (streams without an index)
            meta["count"] = int(count) if np.isfinite(count) and count > 0 else 1
            meta["fps"] = _valid_fps(cap.get(cv2.CAP_PROP_FPS))
        shape = (int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)), int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)))
        raw = (channel is None and int(cap.get(cv2.CAP_PROP_FOURCC)) == _MJPG
               and cap.set(cv2.CAP_PROP_FORMAT, -1))
        null = os.open(os.devnull, os.O_WRONLY) if raw else None
        i = 0
        while True:
            ok, img = cap.read()
            if not ok or img is None:
                break  # end of stream; a truncated file simply ends early
            if raw:
                grey = _quiet_imdecode(img, null) if img.size else None
                if i == 0 and meta is not None and grey is not None and grey.shape == shape:
                    meta["first_jpeg"] = img.copy()
                if grey is None or grey.shape != shape:
                    raw = False  # this frame again, and the rest, decoded by OpenCV
                    cap.release()
                    cap = cv2.VideoCapture(str(path))
                    for _ in range(i):
                        cap.grab()
                    continue
            else:
                grey = _to_grey(img, f"{path} (frame {i})", channel=channel)
            yield grey
            i += 1
    except cv2.error as exc:
        raise FrameError(f"{path}: not a readable video ({_one_line(exc)})") from None
    finally:
        if cap is not None:
            cap.release()
        if null is not None:
            os.close(null)


def to_float(frame: np.ndarray) -> np.ndarray:
    """A frame as float32 in [0, 1], integers scaled by their type's maximum.

    Parameters
    ----------
    frame : ndarray of uint8, uint16 or float
        uint8 is divided by 255, uint16 by 65535; floats pass through as
        float32 (not clipped).

    Returns
    -------
    ndarray of float32
        Same shape as ``frame``.
    """
    frame = np.asarray(frame)
    if frame.dtype == np.uint8:
        return frame.astype(np.float32) / np.float32(255)
    if frame.dtype == np.uint16:
        return frame.astype(np.float32) / np.float32(65535)
    if np.issubdtype(frame.dtype, np.floating):
        return frame.astype(np.float32, copy=False)
    raise FrameError(f"to_float: unsupported pixel type {frame.dtype} "
                     "(expected uint8, uint16 or float)")


# --------------------------------------------------------------------------- writing

def _as_int(frame, i: int, path: Path, bit_depth: int, shape) -> np.ndarray:
    """Validate one output frame and convert it to uint8/uint16 per ``bit_depth``."""
    frame = np.asarray(frame)
    where = f"{path}: frame {i}"
    if frame.ndim != 2 or frame.size == 0:
        raise FrameError(f"{where} has shape {frame.shape}; expected a non-empty 2-D grey frame")
    if shape is not None and frame.shape != shape:
        raise FrameError(f"{where} is {frame.shape[0]}x{frame.shape[1]} (rows x cols), "
                         f"frame 0 is {shape[0]}x{shape[1]}")
    dtype = np.uint8 if bit_depth == 8 else np.uint16
    if frame.dtype == dtype:
        return np.ascontiguousarray(frame)
    if frame.dtype == np.uint8:  # -> 16 bit: 255 * 257 == 65535, exact
        return frame.astype(np.uint16) * np.uint16(257)
    if frame.dtype == np.uint16:  # -> 8 bit: integer round(x / 257), no float detour
        return ((frame.astype(np.uint32) + 128) // 257).astype(np.uint8)
    if np.issubdtype(frame.dtype, np.floating):
        if not np.all(np.isfinite(frame)):
            raise FrameError(f"{where} holds NaN or infinite values")
        top = frame.dtype.type(255 if bit_depth == 8 else 65535)
        return np.rint(np.clip(frame, 0, 1) * top).astype(dtype)
    raise FrameError(f"{where} has pixel type {frame.dtype}; expected float in [0, 1], "
                     "uint8 or uint16")


def _numbered(frames: Iterable, path: Path, bit_depth: int) -> Iterator[np.ndarray]:
    """Validated integer frames; raises if there are none."""
    shape = None
    i = -1
    for i, frame in enumerate(frames):
        img = _as_int(frame, i, path, bit_depth, shape)
        shape = img.shape
        yield img
    if i < 0:
        raise FrameError(f"{path}: no frames to write")


def write_frames(frames: Iterable[np.ndarray], path, *, fps: float = 10.0,
                 bit_depth: int = 8) -> Path:
    """Write a sequence of grey frames atomically; the format follows the path.

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
        Floats in [0, 1] (clipped, then ``round(x * max)``), or uint8/uint16
        (rescaled when ``bit_depth`` differs). Consumed once, streamed.
    path : str or Path
        ``.avi`` (MJPG), ``.mp4`` (mp4v), ``.tif``/``.tiff`` (multi-page,
        zlib-compressed, lossless), or a path with no suffix / an existing
        folder: a folder of ``frame_00000.png``, ``frame_00001.png``, ...
        Missing parent folders are created.
    fps : float
        Frame rate stored in videos and in the TIFF description.
    bit_depth : {8, 16}
        Bits per pixel; 16 only for PNG folders and TIFF.

    Returns
    -------
    Path
        ``path``, now complete. On any error nothing is left at ``path`` (an
        existing output there is kept) and the temporary is removed.

    Raises
    ------
    FrameError
        Bad options, bad frames, no frames, or a format this OpenCV cannot write.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if isinstance(bit_depth, bool) or bit_depth not in (8, 16):
        raise FrameError(f"{path}: bit depth must be 8 or 16, got {bit_depth!r}")
    if _valid_fps(fps) is None:
        raise FrameError(f"{path}: fps must be a positive finite number, got {fps!r}")
    if path.is_dir() or suffix == "":
        return _write_folder(frames, path, bit_depth)
    if suffix in WRITE_VIDEO_FOURCC:
        if bit_depth != 8:
            raise FrameError(f"{path}: videos are 8-bit; write a PNG folder or a TIFF for "
                             "16-bit frames")
        return _write_video(frames, path, float(fps))
    if suffix in TIFF_SUFFIXES:
        return _write_tiff(frames, path, float(fps), bit_depth)
    raise FrameError(f"{path}: unknown output format {suffix}: use .avi, .mp4, .tif, .tiff "
                     "or a folder name (no suffix)")


def _write_folder(frames, path: Path, bit_depth: int) -> Path:
    if path.exists() and not path.is_dir():
        raise FrameError(f"{path}: exists and is not a folder")
    if path.is_dir():
        # the folder is replaced as a whole: never take user files down with it
        others = [p.name for p in path.iterdir() if not _FRAME_NAME_RE.fullmatch(p.name)]
        if others:
            raise FrameError(f"{path}: the folder holds other files ({others[0]}, ...); "
                             "refusing to replace it")
    with atomic_dir(path) as tmp:
        for i, img in enumerate(_numbered(frames, path, bit_depth)):
            if not cv2.imwrite(str(tmp / FRAME_NAME.format(i)), img):
                raise FrameError(f"{path}: could not write frame {i} as PNG")
    return path


def _write_tiff(frames, path: Path, fps: float, bit_depth: int) -> Path:
    import tifffile

    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, tifffile.TiffWriter(tmp) as tif:
        for i, img in enumerate(_numbered(frames, path, bit_depth)):
            # one page per frame (contiguous=False) so readers can stream pages;
            # the first page's JSON description carries the frame rate. (Not as
            # tifffile's shaped metadata: its shape would be the first page's
            # alone, and tifffile warns about such a file on every read.)
            tif.write(img, contiguous=False, compression="zlib", metadata=None,
                      description=json.dumps({"fps": fps}) if i == 0 else None)
    return path


def _open_writer(tmp: Path, path: Path, fps: float, size: tuple[int, int]):
    """A grey VideoWriter (or a colour one fed BGR, if grey is refused), and its mode."""
    fourcc = cv2.VideoWriter_fourcc(*WRITE_VIDEO_FOURCC[path.suffix.lower()])
    for is_color in (False, True):
        writer = cv2.VideoWriter(str(tmp), fourcc, fps, size, isColor=is_color)
        if writer.isOpened():
            # honoured by OpenCV's own MJPEG encoder, ignored (False) by FFmpeg's
            writer.set(cv2.VIDEOWRITER_PROP_QUALITY, 95)
            return writer, is_color
        writer.release()
    raise FrameError(f"{path}: this OpenCV cannot write {path.suffix.lstrip('.').upper()} "
                     f"({WRITE_VIDEO_FOURCC[path.suffix.lower()]}) video")


def _write_video(frames, path: Path, fps: float) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        writer = None
        try:
            for img in _numbered(frames, path, 8):
                if writer is None:
                    writer, is_color = _open_writer(tmp, path, fps, (img.shape[1], img.shape[0]))
                writer.write(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if is_color else img)
        finally:
            if writer is not None:
                writer.release()
        if tmp.stat().st_size == 0:
            raise FrameError(f"{path}: the video writer produced an empty file")
    return path

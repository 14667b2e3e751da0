"""Reading and writing frame sequences: videos, image folders, multi-page TIFFs.

Frames are streamed one at a time (memory stays flat in the number of frames)
as 2-D greyscale arrays in their native dtype (uint8, uint16 or float).
Every problem with the input raises :class:`FrameError` with one line naming
the file and what is wrong.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from pathlib import Path

import cv2
import numpy as np

from .atomic import atomic_dir, atomic_path

IMAGE_SUFFIXES = {".png", ".tif", ".tiff", ".jpg", ".jpeg", ".bmp"}
TIFF_SUFFIXES = {".tif", ".tiff"}
VIDEO_SUFFIXES = {".avi", ".mp4", ".mov", ".mkv", ".m4v", ".mpg", ".mpeg", ".wmv", ".webm"}


class FrameError(ValueError):
    """Unreadable, missing or inconsistent frame input."""


def _natural_key(path: Path):
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", path.name)]


def _to_grey(img: np.ndarray, where: str) -> np.ndarray:
    if img.ndim == 2:
        return img
    if img.ndim == 3 and img.shape[2] == 1:
        return img[:, :, 0]
    if img.ndim == 3 and img.shape[2] in (3, 4):
        code = cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        if img.dtype not in (np.uint8, np.uint16, np.float32):
            img = img.astype(np.float32)
        return cv2.cvtColor(img, code)
    raise FrameError(f"{where}: unsupported image layout {img.shape}")


def _check_dtype(img: np.ndarray, where: str) -> np.ndarray:
    if img.dtype in (np.uint8, np.uint16):
        return img
    if np.issubdtype(img.dtype, np.floating):
        if not np.all(np.isfinite(img)):
            raise FrameError(f"{where}: image holds NaN or infinite values")
        return img.astype(np.float32, copy=False)
    if np.issubdtype(img.dtype, np.integer):
        return np.clip(img, 0, 65535).astype(np.uint16)
    if img.dtype == bool:
        return img.astype(np.uint8) * 255
    raise FrameError(f"{where}: unsupported pixel type {img.dtype}")


def _read_image(path: Path) -> np.ndarray:
    if path.suffix.lower() in TIFF_SUFFIXES:
        import tifffile

        try:
            img = tifffile.imread(path, key=0)
        except Exception as exc:  # tifffile raises many types on corrupt files
            raise FrameError(f"{path}: not a readable TIFF ({type(exc).__name__})") from None
        if img.ndim == 3 and img.shape[2] in (3, 4):
            img = img[:, :, ::-1] if img.shape[2] == 3 else img[:, :, [2, 1, 0, 3]]
    else:
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise FrameError(f"{path}: not a readable image")
    return _check_dtype(_to_grey(img, str(path)), str(path))


class FrameReader:
    """An iterable of greyscale frames; use :func:`open_frames` to make one.

    Attributes
    ----------
    source : Path
    kind : str
        "video", "folder", "tiff" or "image".
    fps : float or None
        Frame rate when the file carries one.
    frame_shape : (rows, cols)
    dtype : numpy dtype
    """

    def __init__(self, source: Path, kind: str, count: int, fps, first: np.ndarray,
                 files: list[Path] | None = None):
        self.source = source
        self.kind = kind
        self._count = count
        self.fps = fps
        self.frame_shape = first.shape
        self.dtype = first.dtype
        self._files = files

    def __len__(self) -> int:
        return self._count

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def __iter__(self) -> Iterator[np.ndarray]:
        if self.kind == "video":
            yield from self._iter_video()
        elif self.kind == "tiff":
            yield from self._iter_tiff()
        else:
            for i, path in enumerate(self._files):
                img = _read_image(path)
                if img.shape != self.frame_shape:
                    raise FrameError(f"{path}: frame {i} is {img.shape[1]}x{img.shape[0]} px, "
                                     f"the first is {self.frame_shape[1]}x"
                                     f"{self.frame_shape[0]}")
                yield img

    def _iter_video(self):
        cap = cv2.VideoCapture(str(self.source))
        try:
            i = 0
            while True:
                ok, img = cap.read()
                if not ok:
                    break
                yield _to_grey(img, f"{self.source} frame {i}")
                i += 1
            if i == 0:
                raise FrameError(f"{self.source}: the video holds no readable frames")
        finally:
            cap.release()

    def _iter_tiff(self):
        import tifffile

        with tifffile.TiffFile(self.source) as tif:
            for i, page in enumerate(tif.pages):
                try:
                    img = page.asarray()
                except Exception as exc:
                    raise FrameError(f"{self.source}: page {i} is unreadable "
                                     f"({type(exc).__name__})") from None
                if img.ndim == 3 and img.shape[2] == 3:
                    img = img[:, :, ::-1]
                yield _check_dtype(_to_grey(img, f"{self.source} page {i}"),
                                   f"{self.source} page {i}")


def open_frames(source) -> FrameReader:
    """Open a video, a folder of images, a multi-page TIFF or a single image.

    Parameters
    ----------
    source : str or Path
        A video OpenCV can read (AVI, MP4, …); a folder of PNG/TIFF/JPEG/BMP
        images, taken in natural name order (frame2 before frame10; other
        files ignored); a TIFF with one or more pages; or one image.

    Returns
    -------
    FrameReader
        Iterable of 2-D frames (native dtype), with ``len``, ``fps`` and
        ``frame_shape``; also a context manager.

    Raises
    ------
    FrameError
        Missing, empty, unreadable or inconsistent input (one line).
    """
    path = Path(source)
    if not path.exists():
        raise FrameError(f"{path}: no such file or folder")
    if path.is_dir():
        files = sorted((p for p in path.iterdir()
                        if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES
                        and not p.name.startswith(".")), key=_natural_key)
        if not files:
            raise FrameError(f"{path}: the folder holds no images "
                             f"({', '.join(sorted(IMAGE_SUFFIXES))})")
        first = _read_image(files[0])
        return FrameReader(path, "folder", len(files), None, first, files)
    if path.stat().st_size == 0:
        raise FrameError(f"{path}: the file is empty (0 bytes)")
    suffix = path.suffix.lower()
    if suffix in TIFF_SUFFIXES:
        import tifffile

        try:
            with tifffile.TiffFile(path) as tif:
                count = len(tif.pages)
                first = tif.pages[0].asarray() if count else None
        except Exception as exc:
            raise FrameError(f"{path}: not a readable TIFF ({type(exc).__name__})") from None
        if not count:
            raise FrameError(f"{path}: the TIFF holds no pages")
        if first.ndim == 3 and first.shape[2] == 3:
            first = first[:, :, ::-1]
        first = _check_dtype(_to_grey(first, str(path)), str(path))
        return FrameReader(path, "tiff", count, None, first)
    if suffix in IMAGE_SUFFIXES:
        first = _read_image(path)
        return FrameReader(path, "folder", 1, None, first, [path])
    if suffix not in VIDEO_SUFFIXES:
        raise FrameError(f"{path}: unsupported file type {suffix or '(none)'}: give a video "
                         "(.avi, .mp4, ...), a TIFF, an image or a folder of images")
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise FrameError(f"{path}: not a readable video (corrupt, or a codec OpenCV "
                             "lacks)")
        ok, img = cap.read()
        if not ok or img is None:
            raise FrameError(f"{path}: the video holds no readable frames")
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        fps = float(cap.get(cv2.CAP_PROP_FPS))
    finally:
        cap.release()
    fps = fps if np.isfinite(fps) and 0 < fps < 1e5 else None
    first = _to_grey(img, str(path))
    return FrameReader(path, "video", max(count, 0), fps, first)


def to_float(frame: np.ndarray) -> np.ndarray:
    """A frame as float32 in [0, 1] (integers scaled by their type's maximum)."""
    if frame.dtype == np.uint8:
        return frame.astype(np.float32) * np.float32(1 / 255)
    if frame.dtype == np.uint16:
        return frame.astype(np.float32) * np.float32(1 / 65535)
    return frame.astype(np.float32, copy=False)


def _to_int(frame: np.ndarray, bit_depth: int) -> np.ndarray:
    top = 255 if bit_depth == 8 else 65535
    dtype = np.uint8 if bit_depth == 8 else np.uint16
    if frame.dtype == dtype:
        return frame
    if frame.dtype in (np.uint8, np.uint16):
        return (to_float(frame) * top).round().astype(dtype)
    return (np.clip(frame, 0, 1) * top).round().astype(dtype)


def write_frames(frames: Iterable[np.ndarray], path, *, fps: float = 10.0,
                 bit_depth: int = 8) -> Path:
    """Write frames atomically; the format follows the path.

    Parameters
    ----------
    frames : iterable of 2-D arrays
        Floats in [0, 1] (clipped) or uint8/uint16.
    path : str or Path
        ``.avi`` (MJPG), ``.mp4`` (mp4v), ``.tif``/``.tiff`` (multi-page), or a
        folder (no suffix) of ``frame_00000.png`` …
    fps : float
        Frame rate stored in videos.
    bit_depth : {8, 16}
        16 for PNG and TIFF only.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if bit_depth not in (8, 16):
        raise FrameError(f"bit depth must be 8 or 16, got {bit_depth!r}")
    if suffix in (".avi", ".mp4"):
        if bit_depth != 8:
            raise FrameError(f"{path}: videos are 8-bit; write PNG or TIFF for 16-bit frames")
        return _write_video(frames, path, fps)
    if suffix in TIFF_SUFFIXES:
        import tifffile

        with atomic_path(path) as tmp, tifffile.TiffWriter(tmp) as tif:
            for frame in frames:
                tif.write(_to_int(frame, bit_depth), contiguous=False, compression="zlib")
        return path
    if suffix == "":
        with atomic_dir(path) as tmp:
            for i, frame in enumerate(frames):
                if not cv2.imwrite(str(tmp / f"frame_{i:05d}.png"), _to_int(frame, bit_depth)):
                    raise FrameError(f"{path}: could not write frame {i}")
        return path
    raise FrameError(f"{path}: unknown output format {suffix}: use .avi, .mp4, .tif or a "
                     "folder name")


def _write_video(frames, path: Path, fps: float) -> Path:
    fourcc = cv2.VideoWriter_fourcc(*("MJPG" if path.suffix.lower() == ".avi" else "mp4v"))
    with atomic_path(path) as tmp:
        writer = None
        try:
            for frame in frames:
                img = _to_int(frame, 8)
                if writer is None:
                    size = (img.shape[1], img.shape[0])
                    writer = cv2.VideoWriter(str(tmp), fourcc, float(fps), size, isColor=False)
                    if not writer.isOpened():
                        raise FrameError(f"{path}: this OpenCV cannot write "
                                         f"{path.suffix.lstrip('.').upper()} video")
                    if hasattr(cv2, "VIDEOWRITER_PROP_QUALITY"):
                        writer.set(cv2.VIDEOWRITER_PROP_QUALITY, 95)
                writer.write(img)
            if writer is None:
                raise FrameError(f"{path}: no frames to write")
        finally:
            if writer is not None:
                writer.release()
    return path

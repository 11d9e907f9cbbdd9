"""Silhouette boundaries from images: ``curve_from_image``.

Pipeline: grey image -> threshold -> polarity -> largest 8-connected component -> fill holes ->
pad -> marching squares (``skimage.measure.find_contours``) -> closed outer boundary.
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike
from PIL import Image, UnidentifiedImageError
from scipy import ndimage
from skimage.filters import threshold_otsu
from skimage.measure import find_contours

from shapetree._errors import ImageError
from shapetree.curves._validate import as_curve, orient

__all__ = [
    "curve_from_image",
    "IMAGE_EXTENSIONS",
    "MAX_IMAGE_PIXELS",
    "max_image_pixels",
    "open_image",
    "read_grey",
]

#: Largest image, in pixels (width x height), that shapetree decodes: 64 megapixels, i.e.
#: 8000 x 8000 (about 64 MB as 8-bit grey, 1.5 GB as the float RGB of detection). Larger
#: files are refused with an :class:`ImageError` before any pixel is decoded, so a
#: "decompression bomb" (a small file claiming a huge size) cannot exhaust memory. Raise
#: it with the environment variable ``SHAPETREE_MAX_PIXELS`` (see :func:`max_image_pixels`).
MAX_IMAGE_PIXELS = 64_000_000
_PIXELS_ENV = "SHAPETREE_MAX_PIXELS"

#: File extensions (lower case, with the dot) read as images.
IMAGE_EXTENSIONS = frozenset(
    {".gif", ".png", ".bmp", ".tif", ".tiff", ".pgm", ".pbm", ".ppm", ".pnm", ".jpg", ".jpeg"}
)
_POLARITIES = ("auto", "bright", "dark")
_EIGHT = np.ones((3, 3), dtype=bool)
_PAD = 2


def max_image_pixels() -> int:
    """The image size limit, in pixels: ``$SHAPETREE_MAX_PIXELS``, else :data:`MAX_IMAGE_PIXELS`.

    Raises
    ------
    ImageError
        If ``SHAPETREE_MAX_PIXELS`` is set but is not a positive integer.
    """
    env = os.environ.get(_PIXELS_ENV, "").strip()
    if not env:
        return MAX_IMAGE_PIXELS
    try:
        value = int(env)
    except ValueError:
        value = 0
    if value < 1:
        raise ImageError(f"{_PIXELS_ENV} must be a positive integer (pixels), got {env!r}")
    return value


def _too_large(name: str, pixels: int, limit: int, size: tuple[int, int] | None = None) -> str:
    what = f"{size[0]}x{size[1]} = {pixels:,} pixels" if size else f"{pixels:,} pixels"
    return (
        f"{name}: image too large: {what}, over the limit of {limit:,} pixels "
        f"(a guard against decompression bombs; set {_PIXELS_ENV} to raise it)"
    )


def _allow_in_pillow(limit: int) -> None:
    """Let Pillow's own bomb guard accept what ``limit`` accepts (only ever raises it).

    Pillow warns (``DecompressionBombWarning``) above ``Image.MAX_IMAGE_PIXELS`` (about 89
    megapixels) and refuses images over twice that; a ``SHAPETREE_MAX_PIXELS`` above it
    would otherwise be undone by Pillow. The default limit is below Pillow's, so by
    default Pillow's setting is left as it is; it is never lowered.
    """
    current = Image.MAX_IMAGE_PIXELS
    if current is not None and limit > current:
        Image.MAX_IMAGE_PIXELS = limit


@contextlib.contextmanager
def open_image(path: str | os.PathLike, name: str | None = None) -> Iterator[Image.Image]:
    """``PIL.Image.open`` with shapetree's size limit, checked before any pixel is decoded.

    Every image file shapetree reads goes through this. The image's header size is
    checked against :func:`max_image_pixels` right after opening, and Pillow's own
    ``DecompressionBombError`` (and ``DecompressionBombWarning``, where warnings are
    turned into errors) become the same one-line :class:`ImageError`. Other failures
    (missing file, unknown format: ``FileNotFoundError``, ``UnidentifiedImageError``,
    ``OSError``) propagate unchanged for the caller to word.

    Parameters
    ----------
    path : path-like
    name : str, optional
        What to call the file in the message (default: ``path``).

    Yields
    ------
    PIL.Image.Image
        The opened, not yet decoded image; closed when the block ends.

    Raises
    ------
    ImageError
        The image has more than :func:`max_image_pixels` pixels.
    """
    name = name or str(path)
    limit = max_image_pixels()
    _allow_in_pillow(limit)
    try:
        im = Image.open(path)
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:
        m = re.search(r"\((\d+) pixels\)", str(exc))
        pixels = int(m.group(1)) if m else limit + 1
        raise ImageError(_too_large(name, pixels, limit)) from None
    with im:
        w, h = im.size
        if w * h > limit:
            raise ImageError(_too_large(name, w * h, limit, (w, h)))
        yield im


def read_grey(image: str | os.PathLike | ArrayLike, name: str | None = None) -> np.ndarray:
    """Return an image as a 2-D grey-level array (uint8 for ordinary 8-bit images).

    Parameters
    ----------
    image : path or array_like
        A file readable by Pillow (converted with ``convert("L")``, so palette images give their
        rendered grey levels, never raw palette indices; 16-bit and float images keep their
        values), or an array of shape ``(h, w)``, ``(h, w, 1)``, ``(h, w, 3)`` (RGB) or
        ``(h, w, 4)`` (RGBA, alpha ignored). Colour arrays are converted with the ITU-R 601 luma
        weights used by Pillow.
    name : str, optional
        What to call the image in error messages.

    Raises
    ------
    ImageError
        If the file is missing or unreadable, larger than :func:`max_image_pixels`, or the
        array is empty or has an unusable shape.
    """
    if isinstance(image, str | os.PathLike):
        path = Path(image)
        name = name or str(path)
        if not path.exists():
            raise ImageError(f"{name}: image file not found")
        if not path.is_file():
            raise ImageError(f"{name}: not a file")
        try:
            with open_image(path, name) as im:
                im.load()
                if im.mode in ("I", "F") or im.mode.startswith("I;16"):
                    arr = np.asarray(im).astype(np.float64)
                else:
                    arr = np.asarray(im.convert("L"))
        except ImageError:
            raise
        except (UnidentifiedImageError, OSError, ValueError) as exc:
            raise ImageError(f"{name}: unreadable image file ({exc})") from None
        if arr.size == 0:
            raise ImageError(f"{name}: the image is empty (size {arr.shape})")
        return arr
    name = name or "image"
    arr = np.asarray(image)
    if arr.dtype == bool:
        arr = arr.astype(np.uint8) * 255
    if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise ImageError(f"{name}: expected a numeric image array, got dtype {arr.dtype}")
    if arr.ndim == 3 and arr.shape[2] in (1, 3, 4):
        if arr.shape[2] == 1:
            arr = arr[:, :, 0]
        else:
            rgb = arr[:, :, :3].astype(np.float64)
            arr = rgb @ np.array([0.299, 0.587, 0.114])
    if arr.ndim != 2:
        raise ImageError(
            f"{name}: expected a 2-D grey image or an (h, w, 3|4) colour image, "
            f"got an array of shape {arr.shape}"
        )
    if arr.size == 0:
        raise ImageError(f"{name}: the image is empty (shape {arr.shape})")
    if not np.all(np.isfinite(arr)):
        raise ImageError(f"{name}: the image contains NaN or inf values")
    return arr


def _default_threshold(grey: np.ndarray, name: str) -> float:
    """Default grey threshold: see :func:`curve_from_image`."""
    values = np.unique(grey)
    if values.size < 2:
        raise ImageError(
            f"{name}: the image is blank (every pixel has the value {values[0]}); no foreground"
        )
    if values.size == 2:
        return float(values.mean())
    if grey.dtype == np.uint8 and values[0] < 127.5 < values[-1]:
        return 127.5
    return float(threshold_otsu(grey))


def _foreground(grey: np.ndarray, threshold: float, polarity: str) -> np.ndarray:
    """Boolean foreground mask for a threshold and polarity ("auto": not the border's class)."""
    bright = grey > threshold
    if polarity == "bright":
        return bright
    if polarity == "dark":
        return ~bright
    border = np.concatenate([bright[0], bright[-1], bright[1:-1, 0], bright[1:-1, -1]])
    return ~bright if border.mean() > 0.5 else bright


def curve_from_image(
    image: str | os.PathLike | ArrayLike,
    *,
    polarity: str = "auto",
    threshold: float | None = None,
    min_area: int = 20,
) -> np.ndarray:
    """Outer boundary of the main silhouette in an image, as a closed curve.

    Parameters
    ----------
    image : path or array_like
        An image file (GIF, PNG, BMP, TIFF, PGM/PBM/PPM, JPG; anything Pillow reads) or an array of
        shape ``(h, w)`` or ``(h, w, 3|4)``. Files are converted to grey with Pillow's
        ``convert("L")`` (palette images give their rendered grey, never raw palette indices).
    polarity : {"auto", "bright", "dark"}, optional
        Which side of the threshold is the shape. ``"auto"``: the class that does *not* dominate
        the image border (more than half of the border pixels), so white-on-black and
        black-on-white silhouettes both work, even when the shape touches the border.
        ``"bright"``: pixels ``> threshold``; ``"dark"``: pixels ``<= threshold``.
    threshold : float, optional
        Grey-level threshold. Default: the midpoint of the two values of a two-valued image
        (127.5 for 0/255); 127.5 for other 8-bit images with values on both sides of it (e.g.
        JPEG-compressed silhouettes); otherwise Otsu's threshold.
    min_area : int, optional
        Minimum pixel count of the shape (its largest 8-connected foreground component).

    Returns
    -------
    numpy.ndarray, shape (n, 2), float64
        The closed outer boundary in pixel coordinates ``(x, y) = (column, row)`` of the original
        image (y points down), without a repeated endpoint, with positive :func:`signed_area`
        (which looks clockwise on screen). The boundary runs through the midpoints between
        foreground and background pixel centres (marching squares at level 0.5), so a disc of
        radius ``r`` gives a curve of radius about ``r``.

    Raises
    ------
    ImageError
        If the file is missing or unreadable, the image is empty, blank (a single value, or no
        pixel on the foreground side of the threshold), or its largest component has fewer than
        ``min_area`` pixels; or on a bad ``polarity``.

    Notes
    -----
    Only the largest 8-connected foreground component is kept, so specks and fragments are
    dropped; its holes are filled (only the outer boundary is traced). The mask is padded with
    background before tracing, so shapes touching the image border get a closed boundary that
    runs along the border.
    """
    if polarity not in _POLARITIES:
        raise ImageError(f"unknown polarity {polarity!r}; expected 'auto', 'bright' or 'dark'")
    name = str(image) if isinstance(image, str | os.PathLike) else "image"
    grey = read_grey(image, name)
    if threshold is None:
        threshold = _default_threshold(grey, name)
    mask = _foreground(grey, float(threshold), polarity)
    if not mask.any():
        raise ImageError(f"{name}: the image is blank (no foreground pixel at this threshold)")
    if mask.all():
        raise ImageError(f"{name}: the image is blank (every pixel is foreground)")

    labels, n_labels = ndimage.label(mask, structure=_EIGHT)
    sizes = np.bincount(labels.ravel())[1:]
    biggest = int(np.argmax(sizes)) + 1
    if sizes[biggest - 1] < min_area:
        raise ImageError(
            f"{name}: foreground too small: the largest component has {sizes[biggest - 1]} "
            f"pixels, fewer than min_area={min_area}"
        )
    shape = ndimage.binary_fill_holes(labels == biggest)
    padded = np.pad(shape, _PAD).astype(np.float64)
    contours = find_contours(padded, 0.5, fully_connected="high")
    # With holes filled there is one closed contour; keep the one enclosing the most area anyway.
    rc = max(contours, key=lambda c: abs(_shoelace(c)))
    xy = rc[:, ::-1] - _PAD
    return orient(as_curve(xy, closed=True, name=name), "ccw")


def _shoelace(pts: np.ndarray) -> float:
    x, y = pts[:, 0], pts[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))

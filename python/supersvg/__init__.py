"""Image vectorization (raster to SVG) with the SuperSVG method.

    >>> import supersvg
    >>> svg = supersvg.vectorize("photo.jpg", paths=500)          # the SVG's text
    >>> supersvg.vectorize(open("photo.jpg", "rb").read(), paths="auto", out="photo.svg")
    >>> supersvg.vectorize(pixels)                                # numpy H×W×3 / H×W×4 uint8

The models ship inside the package; the work runs in Rust with the GIL released.
"""

import os
import warnings

from . import _native

__all__ = ["vectorize", "MAX_PATHS"]

#: The largest path budget :func:`vectorize` accepts.
MAX_PATHS = _native.MAX_PATHS


def vectorize(image, paths=500, *, finetune_secs=None, size=512, fills=None, moves=None, out=None):
    """Draws ``image`` as an SVG and returns its text.

    ``image`` is a path (``str`` or ``os.PathLike``) of a png, jpeg, webp, gif, bmp or tiff file,
    a file's contents as ``bytes``, or an ``H×W`` (grey), ``H×W×3`` (RGB) or ``H×W×4`` (RGBA,
    drawn over white) ``uint8`` array such as numpy's.

    ``paths`` is the most paths to draw (2 to :data:`MAX_PATHS`) or ``"auto"``: as many as the
    image needs. ``finetune_secs`` fine-tunes every path against the image for that many seconds
    (SuperSVG-F). ``size`` is the long side, in pixels, of the working image (the SVG keeps the
    input's size). ``fills`` is what the regions are filled with: ``"flat"`` (each its mean
    colour), ``"linear"`` (a colour ramp where one fits) or ``"auto"`` (a ramp where it draws
    better than its bytes would as regions); ``None`` (the default) is ``"auto"``, but ``"flat"``
    for flat art (icons, emoji); ``finetune_secs`` starts from what B draws with the same fills. ``moves`` says where the mover moves
    the drawn outlines onto the image's edges: ``"auto"`` (the default, ``None``: where the regions
    get ramps, photos), ``"on"`` or ``"off"``. ``out`` also writes the SVG to that file (whole or not at all): a ``.svg`` file,
    never the input, checked before any work.

    Raises ``ValueError`` for an image that cannot be read, an argument out of range or an ``out``
    that is the input or not ``.svg``,
    ``OSError`` (``FileNotFoundError`` …) for a file that cannot be opened or written, ``TypeError``
    for an input of another type. What the job did differently from what was asked (fewer paths
    than the budget, fewer regions) is said with :func:`warnings.warn`.
    """
    budget = _budget(paths)
    if size is None or isinstance(size, bool) or not isinstance(size, int) or size < 0:
        raise ValueError(f"size {size!r} is not a number of pixels")
    if size > _native.MAX_WORKING_SIZE:
        raise ValueError(f"size {size} is not a working size: at most {_native.MAX_WORKING_SIZE} pixels")
    if finetune_secs is not None:
        if isinstance(finetune_secs, bool) or not isinstance(finetune_secs, (int, float)):
            raise ValueError(f"finetune_secs={finetune_secs!r}: give a number of seconds")
        try:
            finetune_secs = float(finetune_secs)
        except OverflowError:
            raise ValueError(f"finetune_secs={finetune_secs}: out of range") from None
    if out is not None:
        out = os.fsdecode(os.fspath(out))
    if fills is not None and not isinstance(fills, str):
        raise ValueError(f"fills={fills!r}: give 'flat', 'linear' or 'auto'")
    if moves is not None and not isinstance(moves, str):
        raise ValueError(f"moves={moves!r}: give 'auto', 'on' or 'off'")
    options = (budget, finetune_secs, size, fills, moves, out)
    if isinstance(image, (str, os.PathLike)):
        svg, said = _native.from_file(os.fsdecode(os.fspath(image)), *options)
    elif isinstance(image, (bytes, bytearray, memoryview)):
        svg, said = _native.from_bytes(bytes(image), *options)
    elif hasattr(image, "__array_interface__") or hasattr(image, "__array__"):
        data, (height, width, channels) = _pixels(image)
        svg, said = _native.from_pixels(data, width, height, channels, *options)
    else:
        raise TypeError(
            f"cannot vectorize a {type(image).__name__}: give a path, a file's bytes or a uint8 array"
        )
    for message in said:
        warnings.warn(message, stacklevel=2)
    return svg


def _budget(paths):
    """``paths`` as the native module takes it: a number, or ``None`` for ``"auto"``."""
    if paths == "auto":
        return None
    if isinstance(paths, bool) or not isinstance(paths, int):
        raise ValueError(f"paths={paths!r}: give a number of paths or 'auto'")
    if paths < 0:
        raise ValueError(f"paths={paths}: a budget is a positive number of paths")
    if paths > MAX_PATHS:
        raise ValueError(f"paths={paths} is out of range: at most {MAX_PATHS}")
    return paths  # the library checks the rest of its range


def _pixels(image):
    """An array's bytes in C order and its ``(height, width, channels)``."""
    import numpy

    array = numpy.asarray(image)
    if array.dtype != numpy.uint8:
        raise ValueError(f"an array of {array.dtype}: give uint8 pixels (0 to 255)")
    if array.ndim == 2:
        array = array[:, :, None]
    if array.ndim != 3 or array.shape[2] not in (1, 3, 4):
        raise ValueError(f"an array of shape {array.shape}: give H×W, H×W×3 (RGB) or H×W×4 (RGBA)")
    return numpy.ascontiguousarray(array).tobytes(), array.shape

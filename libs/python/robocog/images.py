"""Frames as NumPy arrays that borrow the received sample's memory (no copy of the pixels).

A received `msg.RgbdFrame`'s image data are `memoryview`s of the sample as zenoh delivered it (for
a camera on the same machine, the camera's shared-memory buffer); these arrays are views of them,
read-only, and keep the sample alive while they live. Copy what you keep beyond the callback.
"""

from __future__ import annotations

import numpy as np

from . import msg


def _image(image: msg.Image, dtype: np.dtype, channels: int) -> np.ndarray:
    width, height = image.width, image.height
    itemsize = np.dtype(dtype).itemsize
    if image.step < width * channels * itemsize or len(image.data) < image.step * height:
        raise ValueError(
            f"an image of {width}x{height} with rows of {image.step} bytes does not fit in "
            f"{len(image.data)} bytes"
        )
    shape = (height, width, channels) if channels > 1 else (height, width)
    strides = (image.step, channels * itemsize, itemsize) if channels > 1 else (image.step, itemsize)
    return np.ndarray(shape=shape, dtype=dtype, buffer=image.data, strides=strides)


def rgb(frame: msg.RgbdFrame) -> np.ndarray:
    """The colour image, `height x width x 3` uint8 (RGB), borrowed from the sample."""
    return _image(frame.rgb, np.uint8, 3)


def depth_mm(frame: msg.RgbdFrame) -> np.ndarray:
    """The depth image, `height x width` little-endian uint16 millimetres (0: no depth),
    borrowed from the sample."""
    return _image(frame.depth, np.dtype("<u2"), 1)

"""Which preview a file name asks for: a picture (Pillow writes it) or an SVG.

Checked before any work (cli/main.py): a name whose extension no writer knows would
otherwise fail only when the image is saved, after the planning or the whole job.
"""

from __future__ import annotations

import os

from galileo_cnc.errors import GalileoError

SVG = ".svg"
#: pictures of the preview's RGB canvas that Pillow writes (those it has a writer for)
_RASTER = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".gif")


def raster_extensions() -> tuple[str, ...]:
    from PIL import Image           # here: the command line starts without Pillow
    Image.init()
    registered = Image.registered_extensions()
    return tuple(ext for ext in _RASTER if registered.get(ext) in Image.SAVE)


def is_svg(path: str) -> bool:
    """Whether the preview file `path` is the vector preview (preview/svg.py)."""
    return os.path.splitext(path)[1].lower() == SVG


def preview_kind(path: str, option: str) -> str:
    """"svg" or "raster" for the preview file `path`; GalileoError naming `option`
    and the names that work when its extension is none of them."""
    if is_svg(path):
        return "svg"
    ext = os.path.splitext(path)[1].lower()
    pictures = raster_extensions()
    if ext in pictures:
        return "raster"
    what = f"'{ext}' is not an image format it writes" if ext else "the name has no extension"
    raise GalileoError(f"{option} {path}: {what}; name it .png (a picture; also "
                       f"{', '.join(e for e in pictures if e != '.png')}) or .svg (a vector "
                       f"preview a browser can zoom)")

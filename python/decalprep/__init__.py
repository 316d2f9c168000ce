"""decalprep: read `.decals` packages and tilesets (formats/SPEC.md) with
numpy.

    import decalprep
    with decalprep.open("city.decals") as pkg:
        pkg.metadata["grid"]
        [(b.name, b.type, b.count) for b in pkg.blobs]
        v = pkg.array("line_vertices")      # int32, shape (n, 2), quanta
        props = pkg.array("line_props")     # structured: props["half_width"]
    ts = decalprep.open("tileset_dir")      # or ".../tileset.json"
    with ts.open_tile(ts.tiles[0]) as tile:
        ...

Every file is checked as SPEC.md "Validation" and "Index constraints"
require before anything is returned; a file that breaks a rule raises
FormatError (a ValueError) naming the field and the bad value.
"""

import os

from .package import Package
from .spec_reader import FormatError, READER_MAJOR, READER_MINOR
from .tileset import Level, Tile, Tileset

__version__ = "0.1.0"
__all__ = ["open", "Package", "Tileset", "Tile", "Level", "FormatError", "READER_MAJOR", "READER_MINOR"]


def open(path, check_indices=True, mmap=True):  # noqa: A001 - the module's verb, as in gzip.open
    """Opens `path`: a tileset folder or its `tileset.json` gives a Tileset,
    anything else a Package (memory-mapped unless mmap=False;
    check_indices=False leaves out SPEC "Index constraints" and the metadata
    checks of `decalprep verify`, keeping the steps of SPEC "Validation").
    Raises FormatError for an invalid file, OSError when it cannot be read.
    """
    path = os.fspath(path)
    if os.path.isdir(path) or os.path.basename(path) == "tileset.json":
        return Tileset(path)
    return Package(path, check_indices=check_indices, use_mmap=mmap)

"""A validated `.decals` package with its blobs as numpy arrays.

`Package` maps the file read-only and hands the mapping to
`spec_reader.read_package`, which checks it (formats/SPEC.md "Validation",
"Index constraints" and the metadata checks of `decalprep verify`). Blobs
stored with codec `none` are then numpy views of the mapping: no byte of
them is copied. Blobs stored with codec `zstd` are decoded into fresh
buffers while the package is checked.
"""

import json
import mmap
import os
import stat

import numpy as np

from . import spec_reader as sr
from .spec_reader import FormatError


def _file_kind(mode):
    for test, word in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device")):
        if test(mode):
            return word
    return "not a regular file"


def open_regular(path):
    """Opens `path` read-only if it is a regular file (also behind a symbolic
    link) and returns the file descriptor; anything else is refused before a
    byte is read and without blocking (SPEC "Validation": O_NONBLOCK, then
    fstat). Raises FormatError naming what it is, OSError when it cannot be
    opened."""
    mode = os.stat(path).st_mode
    if not stat.S_ISREG(mode):
        raise FormatError("%s: is %s, not a regular file" % (path, _file_kind(mode)))
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):  # replaced between stat and open
            raise FormatError("%s: is %s, not a regular file" % (path, _file_kind(mode)))
    except BaseException:
        os.close(fd)
        raise
    return fd


class Package:
    """One package, checked in full when it is opened.

    Attributes:
      path      the file's path as given
      header    the file header's fields by SPEC name (dict)
      version   (major, minor)
      metadata  the parsed metadata (dict)
      blobs     the blob table in file order: `spec_reader.Blob` entries with
                `name`, `id`, `type` (element type name), `count`, `stride`,
                `codec_name`, `offset`, `stored_size`, `raw_size`, `known`,
                `record` and `dtype`
      mapped    True when the file is memory-mapped (every `none` blob is a
                view of the mapping)

    Not thread-safe to close while another thread reads arrays; reading
    arrays from several threads is fine (they are read-only).
    """

    def __init__(self, path, check_indices=True, use_mmap=True):
        self.path = os.fspath(path)
        self._map = None
        fd = open_regular(self.path)
        try:
            size = os.fstat(fd).st_size
            if use_mmap and size > 0:
                self._map = mmap.mmap(fd, size, access=mmap.ACCESS_READ)
                buf = self._map
            else:
                with os.fdopen(os.dup(fd), "rb") as f:
                    buf = f.read()
        finally:
            os.close(fd)
        try:
            self._p = sr.read_package(buf, self.path)
            errs = sr.check_indices(self._p) + sr.check_metadata(self._p) if check_indices else []
            if errs:
                raise FormatError("%s: %s" % (self.path, "; ".join(errs)))
        except BaseException:
            self.close()
            raise
        self.header = self._p.header
        self.version = (self._p.major, self._p.minor)
        self.metadata = self._p.metadata
        self.blobs = self._p.blobs

    @property
    def mapped(self):
        return self._map is not None

    def __repr__(self):
        return "decalprep.Package(%r, v%d.%d, %d blobs)" % (self.path, self.version[0], self.version[1],
                                                            len(self.blobs))

    # -- access --

    def blob(self, name):
        """The table entry of blob `name`, or None when the package has none."""
        return self._p.blob(name)

    def __contains__(self, name):
        return self._p.blob(name) is not None

    def names(self):
        return [b.name for b in self.blobs]

    def array(self, name):
        """Blob `name` as a read-only numpy array: shape (count,) for
        scalars (plain dtype) and records (structured dtype, fields as in
        SPEC "Records"), (count, n) for vector types; little-endian dtypes.
        An uncompressed blob is a view of the file mapping (np.shares_memory
        with `mapping()`), a compressed one a fresh array. A catalogue blob
        the package lacks reads as empty (SPEC "Blob catalogue"). Raises
        KeyError for a name that is neither in the package nor in the
        catalogue, ValueError after close()."""
        self._check_open()
        b = self._p.blob(name)
        if b is not None:
            return b.array()
        if name not in sr.ID_BY_NAME:
            raise KeyError("%s: no blob named %r" % (self.path, name))
        _, type_name, stride, record = sr.CATALOGUE[sr.ID_BY_NAME[name]]
        dt, shape = sr.element_dtype(sr.TYPE_BY_NAME[type_name], record, stride)
        return np.empty((0,) + shape, dtype=dt)

    def elements(self, name):
        """Blob `name` decoded to Python values as `decalprep dump --json`
        lists them (records as dicts, vectors as lists; NaN stays NaN)."""
        self._check_open()
        b = self._p.blob(name)
        return sr.elements(b) if b is not None else []

    def manifest_entries(self):
        """The `manifest_entries` blob parsed (SPEC "Manifest entries")."""
        b = self._p.blob("manifest_entries")
        return json.loads(bytes(b.data).decode("utf-8")) if b is not None and b.count else []

    def mapping(self):
        """The read-only mmap of the file (None when not mapped)."""
        return self._map

    # -- lifetime --

    def _check_open(self):
        if getattr(self, "_p", None) is None:
            raise ValueError("%s: the package is closed" % self.path)

    def close(self):
        """Drops the package's references to the file. The mapping itself is
        unmapped once no array made from it is left: arrays you still hold
        stay valid (they keep the mapping alive)."""
        self._p = None
        self.blobs = []
        m, self._map = self._map, None
        if m is not None:
            try:
                m.close()
            except BufferError:
                pass  # arrays still view it; it is unmapped when they go

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

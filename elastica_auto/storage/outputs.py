"""The files the reading commands write (`export`'s CSV, `plot`'s figure, `view`'s page):
checked before anything is made, and written atomically.

An output name is easily mistyped into another run's branch file (``-o out/other.h5``), and a
branch file can take hours to compute: an output that is an HDF5 file, or a folder, is
refused, as is the branch file being read under any name. A write goes to a temporary file
beside the output, renamed over it (`store.write_atomically`), so that a failed write leaves
the output as it was; its failure is one `WriteError`.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..core.errors import StoreError, WriteError
from .store import same_file, write_atomically

#: The first bytes of an HDF5 file's superblock (at offset 0, or 512, 1024, 2048, ... when
#: the file starts with a user block).
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def is_hdf5(path: Path) -> bool:
    """Whether the file ``path`` holds an HDF5 superblock where HDF5 looks for one."""
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            offset = 0
            while offset + len(HDF5_SIGNATURE) <= size:
                fh.seek(offset)
                if fh.read(len(HDF5_SIGNATURE)) == HDF5_SIGNATURE:
                    return True
                offset = 512 if offset == 0 else 2 * offset
    except OSError:      # not readable: nothing of it can be lost by a write that fails too
        return False
    return False


def check_output(output, source: Path | None = None, what: str = "the output",
                 doing: str = "read") -> Path:
    """``output`` as a Path; StoreError (one line) if it is the branch file ``source`` (under
    any name or link), a folder, or an existing HDF5 file. ``what`` names the output and
    ``doing`` what is done with ``source`` in the message (``the page``, ``viewed``)."""
    output = Path(output)
    if source is not None and same_file(source, output):
        raise StoreError(f"{output} is the branch file being {doing} ({source}); choose "
                         f"another name for {what}")
    if output.is_dir():
        raise StoreError(f"{output} is a folder; name a file for {what}")
    if output.is_file() and is_hdf5(output):
        raise StoreError(f"{output} is an HDF5 file (a branch file?) and is not overwritten; "
                         f"choose another name for {what}, or remove it first")
    return output


def write_output(output: Path, write, source: Path | None = None, what: str = "the output",
                 doing: str = "read") -> Path:
    """`check_output`, then ``write(tmp)`` on a temporary file beside ``output``, renamed
    over it. WriteError (one line) if it cannot be written: ``output`` is then as it was."""
    output = check_output(output, source, what, doing)
    try:
        return write_atomically(output, write)
    except StoreError as exc:       # write_atomically's: the file could not be written
        raise WriteError(str(exc)) from exc
    except OSError as exc:
        raise WriteError(f"{output}: cannot write ({exc.strerror or exc})") from exc

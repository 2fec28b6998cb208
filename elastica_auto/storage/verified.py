"""The branch files known to match their checksums, so that opening one need not check it again.

Opening a branch file checks every chunk of every dataset against its Fletcher32 checksum
(`store.checksum_failure`): a damaged byte anywhere is reported, whatever a command would
have read. That pass reads the whole file (for `rotating_arm_3d`'s 24 MB, some 50 ms: twice
the rest of the opening). It is needed once per file as it is on disk: this module remembers
the files that passed it, and the files this program wrote (HDF5 made their checksums from
the bytes it wrote), by their identity

    (device, inode, size, modification time, status-change time)   (nanoseconds)

as an empty file named by its digest in ``$XDG_CACHE_HOME/elastica-auto/verified``
(``~/.cache/...`` where that is not set). Any write to a file changes its modification and
status-change times, and a copy is a new inode: a file damaged since, or edited through HDF5,
or copied, is checked again on its next opening. (A user cannot set the status-change time,
so a damaged file cannot pass for a checked one by its times being set back.) Bytes damaged
on the disk itself, below the file system, change neither: those are found by HDF5, which
checks each chunk's checksum whenever it reads it, so no command computes anything from them.

A folder that cannot be written only costs the check next time. The folder is kept to at
most about `MAX_ENTRIES` entries: one write in `PRUNE_EVERY` (those whose entry's digest
starts with "00", so that no write pays for listing the folder but those) removes the
least recently used entries beyond `KEEP`. An entry removed only costs the check of its
file at its next opening.
``ELASTICA_AUTO_CHECKSUMS=always`` checks every file on every opening, remembering nothing.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
from pathlib import Path

#: The environment variable that makes every opening check every chunk ("always").
ENV = "ELASTICA_AUTO_CHECKSUMS"
#: The folder is pruned when it holds more entries than this, ...
MAX_ENTRIES = 4096
#: ... to this many, the most recently used (remembered or looked up) kept; ...
KEEP = 2048
#: ... looked at by one write in this many (the entries whose digest starts with "00").
PRUNE_EVERY = 256


def always() -> bool:
    """Whether every opening checks every chunk (the environment variable says ``always``)."""
    return os.environ.get(ENV, "").strip().lower() == "always"


def folder() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "elastica-auto" / "verified"


def entry_path(st: os.stat_result) -> Path:
    identity = f"{st.st_dev}:{st.st_ino}:{st.st_size}:{st.st_mtime_ns}:{st.st_ctime_ns}"
    return folder() / hashlib.sha256(identity.encode()).hexdigest()[:32]


def known(st: os.stat_result) -> bool:
    """Whether the file of status ``st`` (`os.fstat` of the open file) passed the check, or
    was written by this program, as it is now."""
    if always():
        return False
    entry = entry_path(st)
    try:
        os.utime(entry)          # its use keeps it from pruning
    except FileNotFoundError:
        return False
    except OSError:              # a folder this user cannot write
        return entry.exists()
    return True


def remember(st: os.stat_result):
    """The file of status ``st`` matches its checksums as it is now (best effort)."""
    if always():
        return
    entry = entry_path(st)
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        entry.touch()
    except OSError:
        return
    if entry.name.startswith("00"):          # one write in PRUNE_EVERY, by the digest
        prune(entry.parent)


def prune(where: Path):
    """Remove the least recently used entries beyond KEEP, where there are more than
    MAX_ENTRIES (an entry's modification time is its last use)."""
    with contextlib.suppress(OSError):
        entries = list(os.scandir(where))
        if len(entries) <= MAX_ENTRIES:
            return
        used = []
        for e in entries:
            with contextlib.suppress(OSError):
                used.append((e.stat().st_mtime_ns, e.path))
        used.sort()
        for _, path in used[:max(0, len(used) - KEEP)]:
            with contextlib.suppress(OSError):
                os.unlink(path)

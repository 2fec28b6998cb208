"""HDF5 branch files (docs/hdf5.md): atomic writes, validated reads, CSV export.

Layout of ``out/<run>.h5``::

    /                       attrs: format, format_version, run, equation, created, version,
                            run_file (the TOML text), states, parameters, ordinates (JSON
                            lists), tex (JSON: name -> TeX label), periods (JSON: periodic
                            parameter -> period), labels (JSON: label -> [branch, pt])
    /profile_grid           the fixed s grid of the stored profiles
    /branches/<NNN>/        attrs: parameter, ordinate, direction, start, options, end,
                            message, diagnostics, warnings, seconds
        columns/<name>      one row per point: every parameter and ordinate, arclength, ds,
                            niter, nodes, fold_residual, type, label, note, index,
                            index_rule, index_direct, transition ("1 -> 0" at LP and BP)
        profiles            (distinct profiles, states, grid): every state on
                            /profile_grid, each distinct profile once (`_distinct`)
        profile_rows        (points,): each point's row of profiles (format 3; before,
                            profiles had a row per point)
        solutions/          the exact collocation solutions of the labelled points, packed
                            (`_write_solutions`): label, pt, params, mesh, nodes, s, y, yp,
                            tangent_mesh, tangent_nodes, tangent_s, tangent_y, tangent_yp,
                            tangent_lam; attr tangent_parameter (format 1: a group per
                            label)

    /snaps/                 snap-back targets, one row per (LP, stable equilibrium at its
                            parameters): lp, branch, parameter, value, stable_side, k,
                            index, target_<ordinate>..., on_branch (0: no computed branch);
                            with landings: landed, energy_released, transit_time;
                            profiles (targets, states, grid): each target on /profile_grid
    /landings/              the damped model's landings, one row per (LP, damping): lp,
                            branch, parameter, value, damping, landed, k,
                            target_<ordinate>..., energy_released, transit_time

Format 3: every dataset with data in chunks, shuffled, deflated and Fletcher32-checksummed
(`put`), its strings of fixed length; formats 1 and 2 read as they are (docs/hdf5.md).

Files are built in memory and their bytes written to a temporary name in the same folder,
synced, then renamed over the target (`write_h5`), so a reader never sees a half-written
file and HDF5 never writes to disk: a write that fails (disk full, read-only, too large) is
one `WriteError` (or `StoreError`), the target as it was and no temporary left. While a run
writes it, the file's branches are links to small files of their own, and the file is
written whole at the run's end. A run holds an exclusive lock on its output for as long as it
runs (clearing the locks killed runs left in its folder), and replaces an existing
``<run>.h5`` only once it has finished (see `Writer`).
New files get the mode ``open`` would give them (0666 less the umask).

Reading validates the layout on opening, from the datasets' shapes and the label columns,
and every chunk's checksum: a damaged file raises one `StoreError` naming the file and what
is wrong. Branch columns, profiles and labelled solutions are read when first used, each read
opening and closing the file (see `BranchFile`).
"""

from __future__ import annotations

import contextlib
import csv
import errno
import fcntl
import itertools
import json
import mmap
import os
import re
import shutil
import tempfile
from collections.abc import Mapping
from datetime import datetime, timezone
from pathlib import Path

import h5py
import numpy as np

from .. import FORMAT_VERSION, __version__
from ..branches.branch import (INDEX_COLUMNS, INDEX_UNKNOWN, PROFILE_GRID, Branch, Point,
                               StoredLabel, column_names, export_names)
from ..core.errors import StoreError, WriteError, error_text
from ..core.solution import State, Tangent
from . import verified

FORMAT = "elastica-auto"


def _ordinate_for(problem, parameter):
    return next((o.name for o in problem.ordinates.values() if o.parameter == parameter), "")


def _tex_labels(problem) -> dict[str, str]:
    """Math-mode TeX label of every parameter and ordinate, for plots."""
    out = {}
    for name, obj in [*problem.parameters.items(), *problem.ordinates.items()]:
        out[name] = obj.tex if obj.tex.startswith("$") else f"${obj.tex}$"
    return out


def _new_file_mode() -> int:
    """The mode ``open`` gives a new file: 0666 less the umask (``mkstemp`` gives 0600)."""
    umask = os.umask(0)  # the umask can only be read by setting it
    os.umask(umask)
    return 0o666 & ~umask


def _temporary(path: Path) -> str:
    """A new empty file beside ``path`` named ``.<name>.XXXXXXXX.tmp``, with the mode of a new
    file; `_temporaries` recognises the name."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        # file systems without Unix modes refuse chmod; the file is no less usable
        with contextlib.suppress(OSError):
            os.fchmod(fd, _new_file_mode())
    finally:
        os.close(fd)
    return tmp


def _temporaries(*paths: Path) -> re.Pattern:
    """The names `_temporary` gives for ``paths``: tempfile's 8 characters [a-z0-9_]."""
    names = "|".join(re.escape(p.name) for p in paths)
    return re.compile(rf"\.(?:{names})\.[a-z0-9_]{{8}}\.tmp")


def _lock(lock: Path, target: Path) -> int:
    """Take the exclusive lock ``lock`` (created if need be) for writing ``target``: its fd.

    Never waits: if another process holds it, StoreError, naming the holder (the process id
    and host it wrote into the file, `_sign`). The holder removes the lock file on release
    (`_unlock`); a process that opened it just before then holds a lock on a removed file, so
    the lock counts only if the locked file is still the one at ``lock``. A lock file that no
    process holds (its run was killed) is taken as a free one.
    """
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            current = os.stat(lock)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise StoreError(f"{target}: another run is writing it ({holder}lock {lock} is "
                             "held); wait for it to end or write elsewhere") from None
        except FileNotFoundError:
            current = None  # removed by the holder as it ended: lock the next one
        except OSError:
            os.close(fd)
            raise
        if current is not None and os.path.samestat(os.fstat(fd), current):
            _sign(fd)
            return fd
        os.close(fd)


def _sign(fd: int):
    """Write this process's id and host into the lock file ``fd`` it holds, for the message
    of a run that finds it held. Only a message depends on it: a lock file that cannot be
    written (a full disk) is held all the same. The host is ``uname``'s node name, what
    gethostname() returns on POSIX (fcntl's locks make this module POSIX-only), without
    importing the socket module for it."""
    with contextlib.suppress(OSError):
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()} {os.uname().nodename}\n".encode(), 0)


def _holder(fd: int) -> str:
    """"process PID on HOST; " as the lock file ``fd``'s holder wrote it (`_sign`), or ""."""
    try:
        words = os.pread(fd, 256, 0).decode("utf-8", "replace").split()
    except OSError:
        return ""
    return f"process {words[0]} on {words[1]}; " if len(words) == 2 else ""


def _unlock(fd: int, lock: Path):
    # Removed while still held, so that nobody locks this file after us (see _lock). A lock
    # file that cannot be removed does no harm: the next run locks it again.
    with contextlib.suppress(OSError):
        os.unlink(lock)
    os.close(fd)


#: The name of a run's lock file beside its output ``<run>.h5`` (`Writer`).
_LOCK_NAME = re.compile(r"\..+\.h5\.lock")


def _clear_stale_locks(folder: Path):
    """Remove the lock files in ``folder`` that no process holds: each left by a run killed
    before it could remove its own (SIGKILL, a crash, a module's ``os._exit``). Each is
    taken before it is removed, as `_unlock` removes a held one, so that a run that opened
    it meanwhile finds it gone and locks a new one (`_lock`); one that is held stays."""
    entries = []
    with contextlib.suppress(OSError):
        entries = [e.path for e in os.scandir(folder) if _LOCK_NAME.fullmatch(e.name)]
    for path in entries:
        try:
            fd = os.open(path, os.O_RDWR | os.O_NOFOLLOW)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if os.path.samestat(os.fstat(fd), os.stat(path)):
                os.unlink(path)
        except OSError:
            pass            # held (BlockingIOError), or removed meanwhile
        finally:
            os.close(fd)


#: The errors of a write that starts but cannot be completed: no room (disk full, quota), no
#: writing at all (a read-only file system), a file-size limit, a failing device. They are
#: `WriteError`s (exit status 5); other write errors (no permission, no such folder, a name
#: too long) are user errors (`StoreError`).
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG, errno.EIO})


def _cannot_write(path: Path, exc: OSError) -> WriteError | StoreError:
    """The one-line error of the failed write of ``path``: WriteError for `WRITE_ERRNOS`,
    else StoreError."""
    text = f"{path}: cannot write ({exc.strerror or exc})"
    return WriteError(text) if exc.errno in WRITE_ERRNOS else StoreError(text)


#: The HDF5 object layouts the files are written with: HDF5 1.10's, whose metadata
#: (superblock, object headers, chunk indexes) carries checksums, so that damaged metadata
#: is reported by HDF5 as damaged data is by the datasets' Fletcher32 (`put`). Files are
#: read by HDF5 1.10 and later.
LIBVER = ("v110", "v110")

_IMAGES = itertools.count()


def _image(build) -> bytes:
    """The bytes of the HDF5 file that ``build(f)`` makes of a new file ``f``, built in memory
    (HDF5's core driver without a backing file). No HDF5 call writes to disk: a disk that
    fills up, a file-size limit or a read-only file system is met by `_write_bytes`'s plain
    writes, as an OSError, never inside HDF5 (whose failed writes on a full disk left its
    file half-closed: a segmentation fault in h5py's File.close)."""
    name = f"elastica-auto-image-{os.getpid()}-{next(_IMAGES)}.h5"
    with h5py.File(name, "w", driver="core", backing_store=False, block_size=1 << 20,
                   libver=LIBVER) as f:
        build(f)
        f.flush()
        return f.id.get_file_image()


def _write_bytes(out: Path, data: bytes, stage: str = ""):
    """``data`` written to ``out`` as `_replace` writes (plain writes, synced, renamed): on any
    failure (an OSError), ``out`` is as it was and the temporary is gone."""
    def write(tmp):
        fd = os.open(tmp, os.O_WRONLY)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)

    # HDF5 made these bytes, their checksums with them: the file needs no checking on opening
    verified.remember(_replace(out, write, stage))


def _replace(out: Path, write, stage: str = "") -> os.stat_result:
    """``write(tmp)`` on a new temporary file beside ``out``, the file synced to disk (a crash
    leaves the old file, never a half-written new one) and renamed over ``out``; on any
    failure the temporary is removed and the exception raised. ``stage`` names the write for
    `save_stage`. Returns the status of the file written, taken after the rename (which changes
    its ``st_ctime``) from the file itself, whatever has been renamed over ``out`` since."""
    tmp = _temporary(out)
    try:
        write(tmp)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
            save_stage(f"{stage} written")
            os.replace(tmp, out)
            save_stage(f"{stage} renamed")
            return os.fstat(fd)
        finally:
            os.close(fd)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_h5(out: Path, build, stage: str = "") -> Path:
    """Write the HDF5 file that ``build(f)`` makes to ``out``, atomically: built in memory
    (`_image`), then written beside ``out`` and renamed over it (`_write_bytes`). A failed
    write leaves ``out`` as it was: WriteError (disk full, read-only, too large) or
    StoreError, one line."""
    out = Path(out)
    data = _image(build)
    try:
        _write_bytes(out, data, stage)
    except OSError as exc:
        raise _cannot_write(out, exc) from exc
    return out


class Writer:
    """Writes a run's branch file after each branch, atomically; use it as a context manager.

    Entering checks, before anything is computed, that the output can be written (a folder that
    cannot be created or written, a name too long for the file system, ``<run>.h5`` a directory:
    StoreError); takes an exclusive lock on the output for the whole run, on the hidden file
    ``.<run>.h5.lock`` beside it (a second run writing the same file gets StoreError at once;
    the lock file is removed on exit); and removes the temporary files a killed run left for
    this output.

    Each save writes the branches not written yet, each to a small file of its own in the
    hidden folder ``.<name>.branches`` beside the file (``001.h5``, ...), then the file itself
    anew: its attributes, tables and, for each branch, an HDF5 external link to its file. The
    run's end (`finish`, or leaving the context after an interruption) writes the file once
    more, whole, with the branches' groups copied in, and removes the folder. Every one of
    these writes goes to a temporary name and is renamed over its target, so a reader (or a
    run killed at any moment) never sees a half-written file: the file is there whole, as of
    its last save (with its branches linked, as long as the folder is beside it; a run that
    writes it again first makes it whole), or it is not there yet. No save copies what earlier
    saves wrote. ``path`` is the target ``<run>.h5`` if no such file exists when the run
    starts. Otherwise the saves go to ``<run>.partial.h5`` beside it and `finish` renames that
    over the target once the run has ended, failed branches (MX) or not: an earlier result is
    replaced by a complete one only, and an interrupted or killed rerun leaves it as it was,
    the rerun's branches in the partial file.
    """

    def __init__(self, path: Path, run: str, problem, run_file_text: str = ""):
        self.target = Path(path)
        self.partial = self.target.with_name(f"{self.target.stem}.partial.h5")
        self.path = self.target
        self.run, self.problem, self.text = run, problem, run_file_text
        self.written = 0
        self.kept = 0
        self.labels: dict[str, list[int]] = {}
        self._lock = self.target.with_name(f".{self.target.name}.lock")
        self._fd = -1
        self._created = datetime.now(timezone.utc).isoformat(timespec="seconds")
        self._tables: dict = {"snaps": None, "landings": None, "maps": None}
        #: further attributes of the file's root, JSON text by name (``missing``, ``settings``:
        #: docs/hdf5.md), written with the header of every save
        self.extra: dict[str, str] = {}

    def __enter__(self) -> Writer:
        folder = self.target.parent
        if self.target.is_dir():
            raise StoreError(f"{self.target}: is a directory, not a branch file")
        try:
            folder.mkdir(parents=True, exist_ok=True)
            self._fd = _lock(self._lock, self.target)
        except OSError as exc:
            raise StoreError(f"{self.target}: cannot write in {folder} "
                             f"({exc.strerror or exc})") from None
        try:
            _clear_stale_locks(folder)
            stale = _temporaries(self.target, self.partial)
            for entry in os.scandir(folder):
                if stale.fullmatch(entry.name) and entry.is_file(follow_symlinks=False):
                    os.unlink(entry.path)
            for path in (self.target, self.partial):   # what a killed run left
                _whole(path)
            if self.target.exists():
                self.path = self.partial
            os.unlink(_temporary(self.path))  # the longest name a save needs
        except OSError as exc:
            _unlock(self._fd, self._lock)
            raise StoreError(f"{self.target}: cannot write in {folder} "
                             f"({exc.strerror or exc})") from None
        except BaseException:
            _unlock(self._fd, self._lock)
            raise
        return self

    def __exit__(self, *exc_info):
        from ..core.interrupts import Interruptions
        try:
            # (its folder too if no branch was saved: a run stopped at its first branch)
            with Interruptions():    # the run is ending: a Ctrl-C now stops nothing
                _whole(self.path)
        except (OSError, StoreError, WriteError):  # the file stays as saved, its branches
            pass                      # linked: the next run writing it makes it whole
        finally:
            _unlock(self._fd, self._lock)

    def _failed(self, exc: WriteError | StoreError) -> WriteError | StoreError:
        """``exc``, the failure of a write, with what the output holds after it: the
        branches saved before it (the file as of the last save), and the earlier result
        where a rerun writes beside it."""
        n = self.written
        held = (f"{self.path} holds the {n} branch{'es' if n > 1 else ''} saved before it"
                if n else "no branch saved")
        if self.path != self.target:
            held += f"; the earlier {self.target} is unchanged"
        return type(exc)(f"{exc}; {held}")

    def resume(self, kept: BranchFile, count: int):
        """Continue the branch file ``kept`` (opened) with its first ``count`` branches (the
        others, interrupted, are dropped): they stay as they are, and the branches saved from
        now on follow them, numbered from there."""
        self.labels = {name: list(where) for name, where in kept.labels.items()
                       if where[0] <= count}
        self._tables = {"snaps": kept.snaps, "landings": kept.landings, "maps": kept.maps}
        folder = _branch_folder(self.path)
        try:
            folder.mkdir(exist_ok=True)
        except OSError as exc:
            raise _cannot_write(folder, exc) from exc
        try:
            with h5py.File(kept.path, "r") as f:
                for b in kept.branches[:count]:
                    key = f"{b.number:03d}"
                    write_h5(folder / f"{key}.h5",
                             lambda g, key=key: f.copy(f[f"branches/{key}"], g, "branch"),
                             "branch")
        except OSError as exc:
            raise StoreError(f"{kept.path}: unreadable branch file ({error_text(exc)})") \
                from exc
        self.written = self.kept = count
        self._write_index()

    def save(self, branches: list[Branch], snaps: list[dict] | None = None, maps=None,
             landings: list[dict] | None = None):
        """Write ``branches`` (labels already numbered); earlier ones are kept as written.
        ``snaps``: the snap-back target table, ``maps``: the stability maps, ``landings``:
        the damped model's landings (each replaces any stored one).

        A write that fails (WriteError: the disk full, say) leaves the file as of the last
        save, removes the branch files this save wrote (no file links them), and says so."""
        folder = _branch_folder(self.path)
        count, labels, new = self.written, dict(self.labels), []
        try:
            try:
                folder.mkdir(exist_ok=True)
            except OSError as exc:
                raise _cannot_write(folder, exc) from exc
            for k in range(self.written + 1, self.kept + len(branches) + 1):
                br = branches[k - self.kept - 1]
                new.append(write_h5(
                    folder / f"{k:03d}.h5",
                    lambda f, br=br: _write_branch(f.create_group("branch"), self.problem, br),
                    "branch"))
                for pt, p in enumerate(br.points, start=1):
                    if p.type:
                        labels[p.name] = [k, pt]
                count = k
            if snaps is not None:
                self._tables["snaps"] = snaps
            if landings:
                self._tables["landings"] = landings
            if maps:
                self._tables["maps"] = maps
            self._write_index(count, labels)
        except (WriteError, StoreError) as exc:
            for path in new:
                with contextlib.suppress(OSError):
                    os.unlink(path)
            if not self.written:      # nothing links the folder: it goes, if empty
                with contextlib.suppress(OSError):
                    folder.rmdir()
            raise self._failed(exc) from exc
        # saved once the file links them (an interruption before leaves them unsaved)
        self.written, self.labels = count, labels

    def _write_index(self, count: int | None = None, labels: dict | None = None):
        """The file: header, labels, tables, and a link to each of the first ``count``
        branches' files (default: those saved)."""
        folder = _branch_folder(self.path)
        count = self.written if count is None else count
        labels = self.labels if labels is None else labels

        def build(f):
            self._write_header(f)
            f.attrs["labels"] = json.dumps(labels)
            g = f.create_group("branches")
            for k in range(1, count + 1):
                g[f"{k:03d}"] = h5py.ExternalLink(f"{folder.name}/{k:03d}.h5", "/branch")
            if self._tables["snaps"] is not None:
                _write_table(f, "snaps", self._tables["snaps"])
            if self._tables["landings"]:
                _write_table(f, "landings", self._tables["landings"])
            if self._tables["maps"]:
                _write_maps(f, self._tables["maps"])

        write_h5(self.path, build, "index")

    def finish(self):
        """The run has ended (not interrupted): its file becomes ``<run>.h5`` (see the class).
        A Ctrl-C meanwhile is too late to stop anything: it waits for the file."""
        from ..core.interrupts import Interruptions
        try:
            with Interruptions():
                _whole(self.path)
        except OSError as exc:
            raise self._failed(_cannot_write(self.path, exc)) from exc
        except (WriteError, StoreError) as exc:
            raise self._failed(exc) from exc
        if self.path != self.target:
            try:
                os.replace(self.path, self.target)
            except OSError as exc:
                raise StoreError(f"{self.target}: cannot replace it with {self.path} "
                                 f"({exc.strerror or exc})") from exc
            self.path = self.target

    def _write_header(self, f):
        problem = self.problem
        f.attrs.update(format=FORMAT, format_version=FORMAT_VERSION, run=self.run,
                       equation=problem.source, version=__version__, created=self._created,
                       run_file=self.text, states=json.dumps(problem.states),
                       parameters=json.dumps(problem.parameter_names),
                       ordinates=json.dumps(problem.ordinate_names),
                       tex=json.dumps(_tex_labels(problem)),
                       periods=json.dumps({k: q.period for k, q in problem.parameters.items()
                                           if q.period is not None}),
                       **self.extra)
        put(f, "profile_grid", PROFILE_GRID)


def save_stage(name: str):
    """Where a save is (``"branch written"``, ``"index renamed"``, ...): nothing; the tests
    replace it to stop a run there (tests/test_robustness_files.py)."""


def _branch_folder(path: Path) -> Path:
    """The hidden folder of the branch files that ``path``'s links point to while a run
    writes it (`Writer`)."""
    return path.with_name(f".{path.name}.branches")


def _whole(path: Path):
    """Make the branch file ``path`` whole, if a run left it with its branches linked to the
    files of its folder: write it again with their groups copied in (`write_h5`: atomic),
    then remove the folder; a folder without its file goes too. StoreError if ``path`` cannot
    be read; WriteError or StoreError if it cannot be written."""
    folder = _branch_folder(path)
    if not folder.is_dir():
        return
    if path.is_file():
        try:
            with h5py.File(path, "r") as src:
                g = src.get("branches", {})
                linked = any(isinstance(g.get(key, getlink=True), h5py.ExternalLink)
                             for key in g)
                data = _image(lambda dst: _copy_whole(src, dst)) if linked else None
        except OSError as exc:
            raise StoreError(f"{path}: unreadable branch file ({error_text(exc)})") from exc
        if data is not None:
            try:
                _write_bytes(path, data, "whole")
            except OSError as exc:
                raise _cannot_write(path, exc) from exc
    shutil.rmtree(folder)


def _copy_whole(src, dst):
    """Everything of the open file ``src`` into ``dst``, its linked branches' groups copied
    in (as stored: HDF5 copies the compressed chunks as they are)."""
    dst.attrs.update(src.attrs)
    for name in src:
        if name != "branches":
            src.copy(src[name], dst, name)
    g = dst.create_group("branches")
    for key in src["branches"]:
        src.copy(src["branches"][key], g, key)


def _write_table(f, name: str, rows: list[dict]):
    """/``name``: a table of ``rows`` (/snaps, /landings); numbers as float columns, names
    as strings, and the rows' ``profile`` (if any) as ``profiles``."""
    if name in f:
        del f[name]
    g = f.create_group(name)
    keys = [k for k in rows[0] if k != "profile"] if rows else []
    g.attrs["columns"] = json.dumps(keys)
    if rows and "profile" in rows[0]:
        put(g, "profiles", np.array([row["profile"] for row in rows]))
    for k in keys:
        values = [row[k] for row in rows]
        if isinstance(values[0], str):
            _put_strings(g, k, values)
        else:
            put(g, k, np.asarray(values, dtype=float))


def _read_table(f, name: str) -> list[dict]:
    """The rows of the table /``name`` (`_write_table`), [] if there is none."""
    if name not in f:
        return []
    g = f[name]
    keys = json.loads(g.attrs["columns"])
    # by the low-level reads of `checked_dataset`: opening reads the table
    cols = {k: list(checked_dataset(g, k, None)) for k in keys}
    rows = [dict(zip(keys, vals)) for vals in zip(*cols.values())]
    if g.id.links.exists(b"profiles"):
        for row, prof in zip(rows, checked_dataset(g, "profiles", None)):
            row["profile"] = prof
    return rows


def _write_maps(f, maps):
    """/maps/NNN: one stability map per plane (`analysis.maps.StabilityMap`): attributes
    x, y, fixed (JSON) and extent; datasets cells and the region table."""
    if "maps" in f:
        del f["maps"]
    for k, m in enumerate(maps, 1):
        g = f.create_group(f"maps/{k:03d}")
        g.attrs.update(x=m.x, y=m.y, fixed=json.dumps(m.fixed), extent=np.asarray(m.extent))
        put(g, "cells", m.cells.astype(np.int32))
        for name in ("region_x", "region_y", "stable", "equilibria"):
            put(g, name, np.asarray(getattr(m, name)))


def _read_maps(f) -> list:
    from ..analysis.maps import StabilityMap
    out = []
    for key in sorted(f.get("maps", {})):
        g = f["maps"][key]
        out.append(StabilityMap(str(g.attrs["x"]), str(g.attrs["y"]),
                                json.loads(g.attrs["fixed"]), tuple(map(float, g.attrs["extent"])),
                                g["cells"][()], g["region_x"][()], g["region_y"][()],
                                g["stable"][()], g["equilibria"][()]))
    return out


# The columns of every branch besides its parameters and ordinates.
_FLOAT_COLUMNS = ("arclength", "ds", "fold_residual")
_INT_COLUMNS = ("niter", "nodes", "label", "index", "index_rule", "index_direct")
_STR_COLUMNS = ("type", "note", "transition")


#: Every dataset with data is stored in chunks through three filters, in this order: byte
#: shuffle (the bytes of the values grouped by significance: the sign, exponent and leading
#: mantissa bytes of neighbouring values are alike, and compress), deflate (gzip) at level
#: DEFLATE_LEVEL, and Fletcher32: a checksum of each chunk as stored, which HDF5 checks on
#: every read and `BranchFile` checks for every chunk on opening (`checksum_failure`).
#: Measured (docs/hdf5.md#compression): level 4 makes rotating_arm_3d's file 1% smaller in
#: 20% more time; lzf (faster to read, but h5py's own: other HDF5 readers lack it) makes
#: rotating_arm's 22% larger.
DEFLATE_LEVEL = 1
#: The size of a chunk before compression, at most: a read decompresses the whole chunks it
#: touches, and HDF5 keeps those of at most 1 MiB in its cache. Whole datasets are read but
#: for the labels' solutions, one label at a time (a slice of a few hundred mesh nodes), whose
#: chunks are smaller: 16 KiB, about the size of a label's slice (for rotating_arm_3d, a label
#: read in 1.9 ms against 2.7 ms with chunks of 64 KiB, the file 1.6% larger; 8 KiB gains
#: nothing more).
CHUNK_BYTES = 1 << 20
SOLUTION_CHUNK_BYTES = 1 << 14
#: A branch's profiles are read whole (`StoredBranch.profiles`) or some points at a time
#: (`StoredBranch.profiles_at`: a page or a figure draws its labels), whose chunks are
#: small: 16 KiB, two profiles of the spatial rod. rotating_arm_3d's page reads its 838
#: labels' profiles (of 3,682 points) in 43 ms, against 80 ms with chunks of 1 MiB (every
#: chunk then held a label); the file 1.7% larger.
PROFILE_CHUNK_BYTES = 1 << 14


def put(g, name: str, data: np.ndarray, axis: int = 0, chunk_bytes: int = CHUNK_BYTES):
    """``g[name] = data`` for an array of numbers (or of fixed-length byte strings), compressed
    and checksummed (see DEFLATE_LEVEL), in chunks of at most ``chunk_bytes`` cut along
    ``axis``; an empty array as an empty contiguous dataset (a chunk cannot be empty).

    By h5py's low-level calls: a third of the time of the high-level ones (which build and
    check their property lists each time; a branch writes some fifty datasets, and saving
    was 10% of `rotating_arm -j 1`)."""
    data = np.ascontiguousarray(data)
    dcpl = None
    if data.size:
        chunk = list(data.shape)
        across = data.itemsize * data.size // chunk[axis]   # bytes of one slice along axis
        chunk[axis] = max(1, min(chunk[axis], chunk_bytes // across))
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_chunk(tuple(chunk))
        dcpl.set_shuffle()
        dcpl.set_deflate(DEFLATE_LEVEL)
        dcpl.set_fletcher32()
    dset = h5py.h5d.create(g.id, name.encode(), h5py.h5t.py_create(data.dtype),
                           h5py.h5s.create_simple(data.shape), dcpl=dcpl)
    if data.size:
        dset.write(h5py.h5s.ALL, h5py.h5s.ALL, data)


def _put_strings(g, name: str, values):
    """``g[name]``: the strings ``values`` as fixed-length UTF-8 (`put`: compressed and
    checksummed; the padding compresses away). Not HDF5's variable-length strings: those live
    in a heap of the file that no checksum covers."""
    encoded = [v.encode("utf-8") for v in values]
    width = max(map(len, encoded), default=0) or 1
    array = np.array(encoded, dtype=h5py.string_dtype("utf-8", width))
    put(g, name, array)


def _write_branch(g, problem, br: Branch):
    g.attrs.update(parameter=br.parameter, ordinate=_ordinate_for(problem, br.parameter),
                   direction=br.direction, start=br.start, options=json.dumps(br.options),
                   end=br.end, message=br.message, diagnostics=json.dumps(br.diagnostics),
                   warnings=json.dumps(br.warnings), seconds=br.seconds, worker=br.worker,
                   cell=br.cell)
    cols = g.create_group("columns")
    for name in problem.parameter_names + problem.ordinate_names + list(_FLOAT_COLUMNS):
        put(cols, name, br.column(name).astype(float))
    for name in _INT_COLUMNS:  # the label's number: its name is type and number
        put(cols, name, np.array([p.label for p in br.points] if name == "label"
                                  else br.column(name), dtype=np.int32))
    for name in _STR_COLUMNS:
        _put_strings(cols, name, list(br.column(name)))
    distinct, rows = _distinct([p.profile for p in br.points])
    put(g, "profiles", np.array(distinct), chunk_bytes=PROFILE_CHUNK_BYTES)
    put(g, "profile_rows", rows)
    _write_solutions(g.create_group("solutions"), br)


def _distinct(arrays: list) -> tuple[list, np.ndarray]:
    """The distinct arrays of ``arrays`` (equal bit for bit), in order of first appearance,
    and for each array the index of its own among them. A branch through several periods of
    a parameter repeats its points' profiles and solutions exactly at every period (the
    engine copies them, `branches.stepper`): rotating_arm_3d holds 1712 distinct profiles
    of 3682 and 384 distinct labelled solutions of 838, each stored once."""
    index: dict[bytes, int] = {}
    distinct, rows = [], np.empty(len(arrays), dtype=np.int32)
    for i, a in enumerate(arrays):
        key = a.tobytes() + repr(a.shape).encode()
        if key not in index:
            index[key] = len(distinct)
            distinct.append(a)
        rows[i] = index[key]
    return distinct, rows


def _write_solutions(g, br: Branch):
    """The labelled points' solutions of ``br`` in the group ``g``, packed (format 2 and
    later): one dataset per quantity, the labels' meshes one after the other.

    ``label`` (names), ``pt``, ``params`` (JSON); ``mesh``, for each label the index of its
    solution among the branch's distinct ones (`_distinct`: a solution repeated at a period
    is stored once; format 3); ``nodes`` the offsets of each distinct solution's mesh in
    ``s`` (nodes) and ``y``, ``yp`` (states, nodes); ``tangent_mesh`` (-1: no tangent),
    ``tangent_nodes``, ``tangent_s``, ``tangent_y``, ``tangent_yp`` alike for the tangents,
    and ``tangent_lam`` per label; the attribute ``tangent_parameter``. The meshes' datasets
    are chunked along the nodes in chunks of SOLUTION_CHUNK_BYTES: reading a label
    decompresses a few small chunks, not the branch's every solution."""
    labelled = [(pt, p) for pt, p in enumerate(br.points, start=1) if p.type]
    n = len(br.state_names)
    g.attrs["tangent_parameter"] = br.parameter
    _put_strings(g, "label", [p.name for _, p in labelled])
    put(g, "pt", np.array([pt for pt, _ in labelled], dtype=np.int64))
    _put_strings(g, "params", [json.dumps(p.params) for _, p in labelled])
    tangents = [p.tangent for _, p in labelled]
    for prefix, parts in (("", [p.state for _, p in labelled]), ("tangent_", tangents)):
        given = [x for x in parts if x is not None]
        distinct, rows = _distinct([np.concatenate((x.s[None, :], x.y, x.yp))
                                    for x in given])
        mesh = np.full(len(parts), -1, dtype=np.int32)
        mesh[[k for k, x in enumerate(parts) if x is not None]] = rows
        put(g, f"{prefix}mesh", mesh)
        sizes = [a.shape[1] for a in distinct]
        put(g, f"{prefix}nodes", np.concatenate(([0], np.cumsum(sizes, dtype=np.int64))))
        put(g, f"{prefix}s", np.concatenate([a[0] for a in distinct]) if distinct
             else np.zeros(0), chunk_bytes=SOLUTION_CHUNK_BYTES)
        for q, part in (("y", slice(1, 1 + n)), ("yp", slice(1 + n, 1 + 2 * n))):
            put(g, f"{prefix}{q}", (np.concatenate([a[part] for a in distinct], axis=1)
                                     if distinct else np.zeros((n, 0))),
                 axis=1, chunk_bytes=SOLUTION_CHUNK_BYTES)
    put(g, "tangent_lam", np.array([x.lam if x is not None else np.nan for x in tangents],
                                    dtype=float))


def _read_solution(g, name: str, names: list[str]):
    """Label ``name``'s solution from the branch's ``solutions`` group ``g``: (params,
    s, y, yp, tangent or None, tangent parameter); ``names``: its ``label`` dataset, read.
    Packed (format 2, `_write_solutions`) or, in a file of format 1, a group per label."""
    if "s" not in g or isinstance(g["s"], h5py.Group):          # format 1
        h = g[name]
        state = (json.loads(h.attrs["params"]), h["s"][()], h["y"][()], h["yp"][()])
        if "tangent_y" not in h:
            return (*state, None, None)
        return (*state, Tangent(h["tangent_s"][()], h["tangent_y"][()], h["tangent_yp"][()],
                                float(h.attrs["tangent_lam"])), str(h.attrs["tangent_parameter"]))
    j = names.index(name)
    a, b = _mesh_range(g, "", j)
    params = part_columns(g, "params", j, j + 1)[0]
    state = (json.loads(params.decode() if isinstance(params, bytes) else params),
             part_columns(g, "s", a, b), part_columns(g, "y", a, b), part_columns(g, "yp", a, b))
    ta, tb = _mesh_range(g, "tangent_", j)
    if ta == tb:
        return (*state, None, None)
    return (*state, Tangent(part_columns(g, "tangent_s", ta, tb),
                            part_columns(g, "tangent_y", ta, tb),
                            part_columns(g, "tangent_yp", ta, tb),
                            float(part_columns(g, "tangent_lam", j, j + 1)[0])),
            str(g.attrs["tangent_parameter"]))


def _mesh_range(g, prefix: str, j: int) -> tuple[int, int]:
    """The nodes (a, b) of label number ``j``'s solution (``prefix`` "") or tangent
    ("tangent_") in the packed group ``g``; (0, 0) for no tangent. Format 3 numbers the
    distinct solutions (``mesh``); format 2 stored one per label, in order. A mesh index past
    the stored solutions, or nodes past the stored ones, is ValueError: `part_columns`
    checks the range of each read (of ``nodes`` here, of the solution's datasets after), so
    that no call reads a dataset's shape alone (a label's solution is a dozen calls)."""
    if g.id.links.exists(f"{prefix}mesh".encode()):
        m = int(part_columns(g, f"{prefix}mesh", j, j + 1)[0])
        if m < 0:
            return 0, 0
    else:
        m = j
    a, b = (int(x) for x in part_columns(g, f"{prefix}nodes", m, m + 2))
    if not 0 <= a <= b:
        raise ValueError(f"{prefix}nodes out of order at {m}")
    return a, b


def _dataset(g, name: str):
    """The dataset ``g[name]`` (an h5py DatasetID) by H5Dopen (8% less than H5Oopen);
    KeyError if there is no such member, ValueError if it is no dataset."""
    try:
        return h5py.h5d.open(g.id, name.encode())
    except KeyError:
        if g.id.links.exists(name.encode()):
            raise ValueError(f"{name} is not an array") from None
        raise


def part_columns(g, name: str, a: int, b: int) -> np.ndarray:
    """``g[name][..., a:b]``: the columns a to b of a dataset's last axis, by h5py's
    low-level calls (its high-level slicing costs ten times as much, and a label's solution
    reads a dozen slices); ``a == b == 0`` reads nothing and gives the dataset's shape with
    its last axis first: ``part_columns(g, name, 0, 0).shape[0]`` is that axis' length. KeyError
    for no such member, ValueError for one that is no dataset or a range outside it."""
    obj = _dataset(g, name)
    if not obj.shape:
        raise ValueError(f"{name} is not an array")
    shape = obj.shape
    if (a, b) == (0, 0):
        return np.empty((shape[-1], 0))
    if not 0 <= a <= b <= shape[-1]:
        raise ValueError(f"{name}: columns {a}:{b} of {shape[-1]}")
    count = (*shape[:-1], b - a)
    out = np.empty(count, dtype=obj.dtype)
    if out.size:
        space = obj.get_space()
        space.select_hyperslab((0,) * (len(shape) - 1) + (a,), count)
        obj.read(h5py.h5s.create_simple(count), space, out)
    return out


def part_rows(g, name: str, rows: np.ndarray) -> np.ndarray:
    """``g[name][rows]``: the rows ``rows`` (increasing, distinct, along the first axis) of a
    dataset, each by one low-level read of its hyperslab, so that HDF5 decompresses only the
    chunks holding them (each kept in its chunk cache for the next row). ValueError for a row
    outside the dataset."""
    obj = _dataset(g, name)
    if not obj.shape:
        raise ValueError(f"{name} is not an array")
    shape = obj.shape
    if len(rows) and not (0 <= rows[0] and rows[-1] < shape[0]):
        raise ValueError(f"{name}: rows {rows[0]}..{rows[-1]} of {shape[0]}")
    out = np.empty((len(rows), *shape[1:]), dtype=obj.dtype)
    count = (1, *shape[1:])
    memory = h5py.h5s.create_simple(count)
    space = obj.get_space()
    for k, r in enumerate(rows):
        space.select_hyperslab((int(r),) + (0,) * (len(shape) - 1), count)
        obj.read(memory, space, out[k:k + 1])
    return out


def _solution_names(g) -> list[str] | None:
    """The labels whose solutions the ``solutions`` group ``g`` holds, if packed (format 2);
    None for a group per label (format 1)."""
    if not isinstance(g, h5py.Group) or not isinstance(g.get("label"), h5py.Dataset):
        return None
    return [x.decode() if isinstance(x, bytes) else x for x in g["label"][()]]


class _Source:
    """Where a `BranchFile` reads from: its path, and the identity (device, inode, size,
    modification time) of the file it found there on opening.

    Each read opens the file, checks that it is still that file, reads and closes it: nothing
    stays open between reads, and a file replaced or rewritten since (by a run, say) is never
    read as if it were the same file.
    """

    def __init__(self, path: Path):
        self.path = path
        self.identity: tuple | None = None

    @contextlib.contextmanager
    def open(self):
        """The file, open for reading; StoreError if it is no longer the file first opened."""
        with h5py.File(self.path, "r") as f:
            st = os.fstat(f.id.get_vfd_handle())
            identity = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
            if self.identity is None:
                self.identity = identity
            elif identity != self.identity:
                raise StoreError(f"{self.path}: changed since it was opened (rewritten by a run?); "
                                 "open it again")
            yield f

    def damaged(self, what: str) -> StoreError:
        return StoreError(f"{self.path}: damaged branch file: {what}")

    def read(self, what: str, read):
        """``read(f)`` on the open file; any failure is one StoreError naming ``what``."""
        try:
            with self.open() as f:
                return read(f)
        except StoreError:
            raise
        except FileNotFoundError:
            raise StoreError(f"{self.path}: no such file (removed since it was opened)") from None
        except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:  # HDF5: either
            raise self.damaged(f"{what} unreadable ({error_text(exc)})") from exc


def checked_dataset(g, name: str, shape: tuple | None) -> np.ndarray:
    """The dataset ``g[name]`` as checked on opening (a dataset of ``shape``; None: of any
    shape), read whole; strings decoded. KeyError if it is no longer there, ValueError if it
    changed."""
    try:
        obj = _dataset(g, name)
    except ValueError:
        raise ValueError("no longer the dataset checked on opening") from None
    shape = obj.shape if shape is None else shape
    if obj.shape != shape:
        raise ValueError("no longer the dataset checked on opening")
    if obj.dtype.kind == "O":   # variable-length strings (formats 1, 2): h5py converts them
        data = g[name][()]
    else:   # by the low-level read: a tenth of h5py's own per dataset, and opening reads many
        data = np.empty(shape, dtype=obj.dtype)
        if data.size:
            obj.read(h5py.h5s.ALL, h5py.h5s.ALL, data)
    if data.dtype.kind in "OS":   # strings of either kind, as str
        data = np.array([x.decode() if isinstance(x, bytes) else x for x in data], dtype=object)
    return data


#: Fletcher32's sums are taken mod 65535.
_MOD = 65535
#: The words of a long buffer are summed in rows of this many (`_fletcher32`).
_ROW = 1024
_ROW_INDEX = np.arange(_ROW, dtype=np.int64)


def _fletcher32(data) -> tuple[int, int]:
    """HDF5's Fletcher32 checksum of the bytes ``data`` as its two sums mod 65535: over the
    big-endian 16-bit words w_0 .. w_{n-1} of ``data`` (an odd last byte counts as a word's
    high byte, after them), sum1 = sum w_j and sum2 = sum (n - j) w_j (the sum of sum1's
    running values). In numpy, in one pass over the words laid out in rows of _ROW: with
    j = q _ROW + r, sum2 = sum_q (n - q _ROW) R_q - sum_r r C_r from the rows' sums R_q and
    the columns' sums C_r, each taken mod 65535 so that no product overflows. (HDF5 reduces
    its sums as it goes: the same mod 65535.)"""
    n = len(data) // 2
    words = np.frombuffer(data, dtype=">u2", count=n).astype(np.uint16)
    rows = n // _ROW
    s1 = s2 = 0
    if rows:
        block = words[:rows * _ROW].reshape(rows, _ROW)
        row = block.sum(axis=1, dtype=np.uint64).astype(np.int64) % _MOD
        column = block.sum(axis=0, dtype=np.uint64).astype(np.int64) % _MOD
        s1 = int(row.sum())
        weights = (n - np.arange(rows, dtype=np.int64) * _ROW) % _MOD
        s2 = int(np.dot(weights, row)) - int(np.dot(_ROW_INDEX, column))
    tail = words[rows * _ROW:].astype(np.int64)
    if len(tail):
        s1 += int(tail.sum())
        s2 += int(np.dot(np.arange(n - rows * _ROW, 0, -1), tail))
    if len(data) % 2:
        s1 += int(data[-1]) << 8
        s2 += s1
    return s1 % _MOD, s2 % _MOD


def _checksum_matches(chunk: bytes) -> bool:
    """Whether a chunk as stored (its filtered bytes, then the 4-byte Fletcher32 of those
    that HDF5 appended, little-endian) matches its checksum. Either byte order of the stored
    value matches, as HDF5 allows (files of HDF5 1.6.0-1.6.2 stored it reversed)."""
    s1, s2 = _fletcher32(chunk[:-4])
    trailer = bytes(chunk[-4:])
    for stored in (int.from_bytes(trailer, "little"), int.from_bytes(trailer, "big")):
        if (stored & 0xFFFF) % _MOD == s1 and (stored >> 16) % _MOD == s2:
            return True
    return False


def _chunks(dsid) -> list[tuple[int, int, int]]:
    """(address in the file, size, filter mask) of each stored chunk of the dataset ``dsid``;
    [] for a dataset not stored in chunks."""
    out = []
    try:
        if hasattr(dsid, "chunk_iter"):  # HDF5 1.14: one call
            dsid.chunk_iter(lambda c: out.append((c.byte_offset, c.size, c.filter_mask)))
        else:
            for i in range(dsid.get_num_chunks()):
                c = dsid.get_chunk_info(i)
                out.append((c.byte_offset, c.size, c.filter_mask))
    except RuntimeError:        # "not a chunked dataset"
        return []
    return out


def checksum_failure(group, where: str) -> str | None:
    """The name (``where`` the path of ``group``) of the first dataset under ``group``, in
    its own file (links to other files are not followed), a chunk of which does not match
    its Fletcher32 checksum; None if every chunk matches. Each chunk is read as stored, by
    its address in the file, and not decompressed: for rotating_arm_3d's 45 MB (1600 chunks
    of 900 datasets) about 0.1 s, half of it HDF5's listing of the chunks. A dataset whose
    chunks do not match is looked at once more: one without the filter (formats 1 and 2:
    contiguous, no chunks; a dataset someone added) has no checksum to match."""
    names = []
    group.id.links.visit(names.append)
    fd = group.file.id.get_vfd_handle()
    size = os.fstat(fd).st_size
    with contextlib.ExitStack() as stack:
        image = stack.enter_context(mmap.mmap(fd, size, access=mmap.ACCESS_READ)) \
            if size else b""
        view = stack.enter_context(memoryview(image))
        for name in names:
            dsid = h5py.h5o.open(group.id, name)
            if not isinstance(dsid, h5py.h5d.DatasetID):
                continue
            skipped = None               # the mask bit of the filter, where it is one
            for address, length, mask in _chunks(dsid):
                if mask:
                    dcpl = dsid.get_create_plist()
                    if not _has_fletcher32(dcpl):
                        break
                    skipped = skipped or 1 << _filter_index(dcpl, h5py.h5z.FILTER_FLETCHER32)
                    if mask & skipped:   # the filter was skipped for this chunk
                        continue
                if address + length > size or length < 4 \
                        or not _checksum_matches(view[address:address + length]):
                    if _has_fletcher32(dsid.get_create_plist()):
                        return f"{where.rstrip('/')}/{name.decode()}"
                    break
    return None


def _has_fletcher32(dcpl) -> bool:
    return dcpl.get_filter_by_id(h5py.h5z.FILTER_FLETCHER32) is not None


def _filter_index(dcpl, code: int) -> int:
    """The place of the filter ``code`` in the dataset's pipeline (its bit in a chunk's mask
    of the filters not applied)."""
    return next(i for i in range(dcpl.get_nfilters()) if dcpl.get_filter(i)[0] == code)


def _shapes(g, names=None) -> dict[str, tuple | None]:
    """The shape of each member of the group ``g``, or of those of ``names`` it has (None:
    not a dataset, or a link to nothing), read without reading any data. h5py's low-level
    objects: its high-level ones cost tens of microseconds each, and opening a file looks at
    every column of every branch; H5Dopen, which refuses anything but a dataset, costs 8%
    less than H5Oopen."""
    out = {}
    for name in (g if names is None else [k for k in names if g.id.links.exists(k.encode())]):
        try:
            out[name] = h5py.h5d.open(g.id, name.encode()).shape
        except KeyError:        # "not a dataset"
            out[name] = None
    return out


def _has_solution(solutions, name: str) -> bool:
    """Whether the group ``solutions`` holds a group ``name`` with members s, y and yp (a
    label's stored solution); low-level h5py, as in `_shapes`: a file can hold thousands of
    labels."""
    if not isinstance(solutions, h5py.Group):
        return False
    try:
        sol = h5py.h5o.open(solutions.id, name.encode())
    except KeyError:
        return False
    return isinstance(sol, h5py.h5g.GroupID) and all(sol.links.exists(k)
                                                     for k in (b"s", b"y", b"yp"))


class _Columns(Mapping):
    """The columns of one stored branch by name, in the order of `StoredBranch.columns`.

    ``branch`` and ``pt`` are made here; ``label`` (the label's name, made of the stored
    ``type`` and label number) may be given on opening; every other column is read from the
    file the first time it is looked up, then kept. ``items()`` and ``values()`` read all
    columns not read yet at once (one opening of the file, not one per column).
    """

    def __init__(self, source: _Source, key: str, names: list[str], n: int):
        self._source, self._key, self._n = source, key, n
        self._names = dict.fromkeys(names)
        self._data = {"branch": np.full(n, int(key)), "pt": np.arange(1, n + 1)}

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._data:
            if name not in self._names:
                raise KeyError(name)
            self.load([name])
        return self._data[name]

    def _unread(self, names) -> list[str]:
        """Those of the columns ``names`` (default: all) not read yet; KeyError for one that
        the branch does not have."""
        names = list(self._names if names is None else names)
        unknown = [name for name in names if name not in self._names]
        if unknown:
            raise KeyError(unknown[0])
        return [name for name in names if name not in self._data]

    def load(self, names=None):
        """Read the columns ``names`` (default: all) not read yet, in one opening of the file."""
        todo = self._unread(names)
        if todo:
            what = f"column {todo[0]!r}" if len(todo) == 1 else "columns"
            self._data |= self._source.read(f"branch {self._key}: {what}",
                                            lambda f: _read_columns(f, self._key, todo, self._n))

    def load_from(self, f, names=None):
        """Read the columns ``names`` (default: all) not read yet from ``f``, the file open."""
        todo = self._unread(names)
        if todo:
            self._data |= _read_columns(f, self._key, todo, self._n)

    def keep(self, data: dict[str, np.ndarray]):
        """Columns already read (on opening)."""
        self._data |= data

    def items(self):
        self.load()
        return super().items()

    def values(self):
        self.load()
        return super().values()

    def __iter__(self):
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)

    def __contains__(self, name) -> bool:
        return name in self._names

    def __repr__(self) -> str:
        return f"<columns of branch {self._key} ({self._n} points): {', '.join(self._names)}>"


def _read_columns(f, key: str, names: list[str], n: int) -> dict[str, np.ndarray]:
    """The stored columns ``names`` of branch ``key`` (``n`` points) from the open file.
    ``label`` is the label's name: the file keeps its type and number, a branch in memory
    its name, so reading ``label`` reads ``type`` too (and returns both)."""
    g = f[f"branches/{key}/columns"]
    out = {}
    for name in names:
        if name == "label":
            types = out.get("type")
            if types is None:
                out["type"] = types = checked_dataset(g, "type", (n,))
            out["label"] = np.array([f"{t}{k}" if t else "" for t, k in
                                     zip(types, checked_dataset(g, "label", (n,)))], dtype=object)
        elif name not in out:
            out[name] = checked_dataset(g, name, (n,))
    return out


class StoredBranch:
    """A branch read back from a file: its attributes, columns and profiles.

    ``columns`` maps each column name of a branch in memory
    (`branches.branch.column_names`, in that order, then any other stored column) to one
    numpy array per column, one row per point; ``label`` holds label names (``LP3``, ``""``
    elsewhere). ``profiles`` is the array (points, states, grid) of every state on the file's
    profile grid. Both are read from the file on first access (a column at a time) and kept;
    ``attrs``, ``number`` and ``len`` are known from opening.
    """

    def __init__(self, source: _Source, number: int, attrs: dict, columns: _Columns,
                 profiles_shape: tuple):
        self.number, self.attrs, self.columns = number, attrs, columns
        self._source, self._profiles_shape = source, profiles_shape
        self._profiles: np.ndarray | None = None

    @property
    def profiles(self) -> np.ndarray:
        if self._profiles is None:
            key = f"{self.number:03d}"

            def read(f):
                g = f[f"branches/{key}"]
                if "profile_rows" not in g:    # before format 3: a profile per point
                    return checked_dataset(g, "profiles", self._profiles_shape)
                rows = g["profile_rows"][()]
                distinct = g["profiles"][()]
                if rows.shape != self._profiles_shape[:1] or len(rows) and not (
                        0 <= rows.min() and rows.max() < len(distinct)):
                    raise ValueError("profile_rows does not index the profiles")
                return distinct[rows]

            self._profiles = self._source.read(f"branch {key}: profiles", read)
        return self._profiles

    def profiles_at(self, rows) -> np.ndarray:
        """``profiles[rows]`` (points ``rows``, 0-based), reading only those profiles: the
        chunks that hold them are decompressed, not the branch's whole profiles (a page of
        rotating_arm_3d draws its labels' 59 profiles from 6,800). IndexError for a row
        outside the branch."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        n = self._profiles_shape[0]
        if len(rows) and not (-n <= rows.min() and rows.max() < n):
            raise IndexError(f"branch {self.number}: rows outside its {n} points")
        rows = rows % n if n else rows
        if self._profiles is not None:
            return self._profiles[rows]
        key = f"{self.number:03d}"

        def read(f):
            g = f[f"branches/{key}"]
            wanted = np.unique(rows)
            if "profile_rows" not in g:     # before format 3: a profile per point
                return part_rows(g, "profiles", wanted)[np.searchsorted(wanted, rows)]
            stored = checked_dataset(g, "profile_rows", (n,))[wanted]
            distinct = np.unique(stored)
            profiles = part_rows(g, "profiles", distinct)
            return profiles[np.searchsorted(distinct, stored)][np.searchsorted(wanted, rows)]

        return self._source.read(f"branch {key}: profiles", read)

    @property
    def parameter(self) -> str:
        return self.attrs["parameter"]

    def __len__(self):
        return self._profiles_shape[0]

    def label_names(self) -> list[str]:
        return list(self.columns["label"])

    def __repr__(self) -> str:
        return f"<StoredBranch {self.number} of {self._source.path}: {len(self)} points>"


class BranchFile:
    """A read-only view of an elastica-auto HDF5 file; raises StoreError with one line.

    Opening reads the file's attributes, profile grid, snap-back table and landings (the
    damped model's: ``landings``), and checks the
    whole layout from the datasets' shapes: each branch has every column, each a
    one-dimensional dataset of one length, at least one point, and a profile per point; the
    ``labels`` attribute maps each label to a point of that label whose solution is stored
    (for which the ``type`` and ``label`` columns of the branches holding labels are read).
    It checks every stored chunk of every dataset against its Fletcher32 checksum (format 3;
    `checksum_failure`), without decompressing them. A file that fails a check is
    reported as damaged, naming what is wrong (``checksum mismatch in /branches/001/...``).
    The other columns and the profiles are read
    when first used (see `StoredBranch`), and a label's solution by `label`: each read opens
    the file and closes it again, and raises StoreError if the file was damaged, or replaced
    or rewritten, since it was opened. ``rows``: read on opening, in the same opening of the
    file, the columns `rows` gives of every branch (`show` and `export` read the file once,
    and a file replaced meanwhile cannot mix into their table).
    """

    def __init__(self, path: str | os.PathLike, rows: bool = False):
        self.path = Path(path)
        self._source = _Source(self.path)
        self._maps = None
        self._solutions: dict[int, list[str] | None] = {}   # labels of packed solutions
        try:
            found = self.path.is_file()
        except OSError as exc:      # a name too long, say
            raise StoreError(f"{self.path}: cannot read ({exc.strerror or exc})") from None
        if not found:
            raise StoreError(f"{self.path}: no such file")
        try:
            with self._source.open() as f:
                attrs = dict(f.attrs)
                if attrs.get("format") != FORMAT:
                    raise StoreError(f"{self.path}: not an elastica-auto branch file")
                version = int(attrs.get("format_version", -1))
                if version > FORMAT_VERSION:
                    raise StoreError(f"{self.path}: file format version {version} is newer than "
                                     f"this elastica-auto reads ({FORMAT_VERSION}); upgrade")
                self.attrs = {k: (v.decode() if isinstance(v, bytes) else v)
                              for k, v in attrs.items()}
                self.parameters = json.loads(self.attrs["parameters"])
                self.ordinates = json.loads(self.attrs["ordinates"])
                self.states = json.loads(self.attrs["states"])
                self.tex = json.loads(self.attrs["tex"])
                self.periods = json.loads(self.attrs.get("periods", "{}"))
                self.labels = self._labels(self.attrs["labels"])
                linked = self._linked(f)
                self.profile_grid = f["profile_grid"][()]
                self.snaps, self.landings = _read_table(f, "snaps"), _read_table(f, "landings")
                self.branches = [self._branch(key, f["branches"][key])
                                 for key in sorted(f.get("branches", {}))]
                self._check_labels(f)
                self._check_sums(f, linked)
                if rows:
                    names = export_names(self.parameters, self.ordinates)
                    for b in self.branches:
                        b.columns.load_from(f, names)
        except StoreError:
            raise
        except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:  # HDF5: either
            raise StoreError(f"{self.path}: unreadable branch file ({error_text(exc)})") from exc

    def _linked(self, f) -> list[str]:
        """The branches the open file ``f`` links from its hidden folder (`Writer`: a file a
        run writes, or a killed run left); StoreError if one's file is missing (the file was
        copied without its folder)."""
        g = f.get("branches", {})
        linked = [key for key in g if isinstance(g.get(key, getlink=True), h5py.ExternalLink)]
        for key in linked:
            target = self.path.parent / g.get(key, getlink=True).filename
            if not target.is_file():
                raise StoreError(
                    f"{self.path}: its branches are in the hidden folder "
                    f"{_branch_folder(self.path).name} beside it, which is missing ({target} "
                    f"is not there): the file of a run that was killed or is running, copied "
                    f"without that folder; in the file's own folder, `elastica-auto run "
                    f"{self.attrs.get('run', 'RUN')} --resume` (or any run writing it) makes "
                    f"the file whole")
        return linked

    def _check_sums(self, f, linked: list[str]):
        """Every chunk of every checksummed dataset matches its checksum (`checksum_failure`),
        the linked branches' files' too; else the file is damaged, naming the dataset. A file
        that passed, or that this program wrote, is not checked again as long as it is
        unchanged (`verified`)."""
        for group, where in [(f, "/")] + [(f["branches"][key], f"/branches/{key}")
                                          for key in linked]:
            st = os.fstat(group.file.id.get_vfd_handle())
            if verified.known(st):
                continue
            bad = checksum_failure(group, where)
            if bad is not None:
                raise self._damaged(f"checksum mismatch in {bad}")
            verified.remember(st)

    def _damaged(self, what: str) -> StoreError:
        return self._source.damaged(what)


    def _labels(self, text: str) -> dict[str, tuple[int, int]]:
        try:
            labels = json.loads(text)
        except ValueError as exc:
            raise self._damaged(f"attribute 'labels' is not JSON ({exc})") from None
        if not isinstance(labels, dict) or not all(
                isinstance(v, list) and len(v) == 2 and all(type(x) is int for x in v)
                for v in labels.values()):
            raise self._damaged("attribute 'labels' is not a map of label -> [branch, point]")
        return {k: tuple(v) for k, v in labels.items()}

    def _branch(self, key: str, g) -> StoredBranch:
        """Branch ``key``'s layout checked from the shapes of its datasets; nothing read."""
        lengths = {}
        for name, shape in _shapes(g["columns"]).items():
            if shape is None or len(shape) != 1:
                raise self._damaged(f"branch {key}: column {name!r} is not a one-dimensional "
                                    "dataset")
            lengths[name] = shape[0]
        missing = [name for name in (*self.parameters, *self.ordinates, *_FLOAT_COLUMNS,
                                     *_INT_COLUMNS, *_STR_COLUMNS) if name not in lengths]
        if missing:
            raise self._damaged(f"branch {key}: no column {', '.join(map(repr, missing))}")
        counts = list(lengths.values())
        n = max(counts, key=counts.count)  # the length of most columns: the odd one is wrong
        odd = next((name for name, m in lengths.items() if m != n), None)
        if odd is not None:
            raise self._damaged(f"branch {key}: column {odd!r} has {lengths[odd]} rows, "
                                f"the others {n}")
        profiles = _shapes(g, ("profiles", "profile_rows"))
        shape = profiles.get("profiles")
        if not shape:
            raise self._damaged(f"branch {key}: 'profiles' is not a dataset of one profile "
                                "per point")
        if n == 0:   # every branch has its start at least (an MX one, if all else failed)
            raise self._damaged(f"branch {key} has no points")
        rows = "profile_rows" in profiles  # format 3: the distinct profiles, and each point's
        if rows and profiles["profile_rows"] != (n,):
            raise self._damaged(f"branch {key}: 'profile_rows' is not a dataset of one row "
                                f"per point ({n})")
        if not rows and shape[0] != n:
            raise self._damaged(f"branch {key}: {shape[0]} profiles for {n} points")
        names = column_names(self.parameters, self.ordinates)
        names += [name for name in lengths if name not in names]
        return StoredBranch(self._source, int(key), dict(g.attrs),
                            _Columns(self._source, key, names, n), (n, *shape[1:]))

    def _check_labels(self, f):
        """Each label names a point with that label, and its solution is stored: reads the
        ``type`` and ``label`` columns of each branch that holds a label (and keeps them)."""
        by_number = {b.number: b for b in self.branches}
        names, solutions = {}, {}
        for name, (br, pt) in self.labels.items():
            b = by_number.get(br)
            if b is not None and br not in names:
                key = f"{br:03d}"
                read = _read_columns(f, key, ["label"], len(b))
                b.columns.keep(read)
                names[br] = read["label"]
            if b is None or not 1 <= pt <= len(b) or names[br][pt - 1] != name:
                raise self._damaged(f"label {name} is at branch {br} point {pt}, but there is "
                                    f"no point {name} there")
            if br not in solutions:
                g = f.get(f"branches/{br:03d}/solutions")
                solutions[br] = (g, _solution_names(g))
                self._solutions[br] = solutions[br][1]
            g, packed = solutions[br]
            if not (name in packed if packed is not None else _has_solution(g, name)):
                raise self._damaged(f"label {name} has no stored solution "
                                    f"(in branches/{br:03d}/solutions)")

    @property
    def run(self) -> str:
        return self.attrs["run"]

    @property
    def equation(self) -> str:
        return self.attrs["equation"]

    @property
    def missing(self) -> list[dict]:
        """What the run that wrote the file could not make (its snap-back scan, landings or
        stability maps failed): one record each, ``what`` ("snaps", "landings", "maps"),
        ``message``, ``kind`` and the exception (`elastica_auto.core.errors.failure_record`);
        empty if nothing is missing (and in files written before 0.2.0)."""
        try:
            out = json.loads(self.attrs.get("missing", "[]"))
        except ValueError:
            raise self._damaged("attribute 'missing' is not JSON") from None
        if not isinstance(out, list) or not all(isinstance(m, dict) and "what" in m
                                                for m in out):
            raise self._damaged("attribute 'missing' is not a list of records")
        return out

    def label_ranges(self) -> str:
        """The labels in the file, compactly: ``EP1-EP16, LP1-LP50, UZ1-UZ276``."""
        counts = {}
        for lab in self.labels:
            counts[lab[:2]] = max(counts.get(lab[:2], 0), int(lab[2:]))
        return ", ".join(f"{t}1-{t}{n}" if n > 1 else f"{t}1"
                         for t, n in sorted(counts.items())) or "none"

    @property
    def maps(self) -> list:
        """The stability maps a fold-curve run stored (`analysis.maps.StabilityMap`, one
        per plane; none for other runs), read from the file on first use."""
        if self._maps is None:
            self._maps = self._source.read("maps", _read_maps)
        return self._maps

    def in_memory(self, b: StoredBranch, problem) -> Branch:
        """Stored branch ``b`` as the `Branch` of ``problem`` it was saved from, for the
        analyses of a run's branches (a resumed run's snap-back targets and landings of the
        branches it keeps, `execution.run._analyse`): each point's parameters, ordinates,
        index columns, label, note and profile, and each labelled point's solution and
        tangent, exactly as stored (the columns and solutions are stored at full precision);
        the BPs' decisions of `analysis.snaps.mark_subcritical` read back from their notes.
        Everything is read now (StoreError if it cannot be)."""
        from ..analysis.snaps import read_subcritical
        try:
            options = json.loads(b.attrs.get("options", "{}"))
        except ValueError:
            raise self._damaged(f"branch {b.number:03d}: attribute 'options' is not JSON") \
                from None
        br = Branch.of(problem, b.parameter, int(b.attrs["direction"]), str(b.attrs["start"]),
                       options, end=str(b.attrs.get("end", "")),
                       message=str(b.attrs.get("message", "")), number=b.number,
                       cell=str(b.attrs.get("cell", "")))
        c, profiles = b.columns, b.profiles
        names = [str(q) for q in c["label"]]
        for k in range(len(b)):
            kind, name = str(c["type"][k]), names[k]
            point = Point(params={q: float(c[q][k]) for q in self.parameters},
                          ordinates={o: float(c[o][k]) for o in self.ordinates},
                          arclength=float(c["arclength"][k]), ds=float(c["ds"][k]),
                          niter=int(c["niter"][k]), nodes=int(c["nodes"][k]), type=kind,
                          profile=profiles[k], fold_residual=float(c["fold_residual"][k]),
                          note=str(c["note"][k]), label=int(name[len(kind):]) if kind else 0,
                          **{q: int(c[q][k]) for q in INDEX_COLUMNS})
            if kind:
                stored = self.label(name)
                point.state, point.tangent = stored.state, stored.tangent
            br.points.append(point)
        read_subcritical(br)
        return br

    def label(self, name: str) -> StoredLabel:
        """The solution stored under a label such as ``UZ3`` (StoreError if there is none),
        read from the file now."""
        if name not in self.labels:
            raise StoreError(f"{self.path}: no label {name!r} (labels: {self.label_ranges()})")
        br, pt = self.labels[name]

        def read(f):
            params, s, y, yp, tangent, tpar = _read_solution(
                f[f"branches/{br:03d}/solutions"], name, self._solutions.get(br) or [])
            return State(s, y, yp, params), tangent, tpar

        # checked on opening; what is left: a solution's own datasets and attributes
        state, tangent, tpar = self._source.read(f"solution {name}", read)
        branch = next((b for b in self.branches if b.number == br), None)
        try:
            options = json.loads(branch.attrs.get("options", "{}")) if branch else {}
        except ValueError:
            options = {}
        return StoredLabel(name, br, pt, state, tangent, tpar, self.path, self.equation,
                           tuple(self.states), options if isinstance(options, dict) else {})


def _fmt(v):
    return "" if v == INDEX_UNKNOWN else str(int(v))


def rows(bf: BranchFile, labelled_only=False):
    """Yield one dict per point, of its export columns (`branches.branch.export_names`):
    parameters and ordinates as floats, indices as text ('' where unknown)."""
    names = export_names(bf.parameters, bf.ordinates)
    for b in bf.branches:
        c = b.columns
        c.load(names)
        for i in range(len(b)):
            if labelled_only and not c["type"][i]:
                continue
            row = {k: c[k][i] for k in names}
            for k in ("branch", "pt"):
                row[k] = int(row[k])
            for k in bf.parameters + bf.ordinates:
                row[k] = float(row[k])
            for k in INDEX_COLUMNS:
                row[k] = _fmt(row[k])
            yield row


def same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` are one existing file, however spelled or linked."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist
        return False


def write_atomically(out: Path, write, stage: str = "") -> Path:
    """Call ``write(tmp)`` on a temporary file beside ``out``, sync it to disk and rename it
    over ``out``, so that a failed write leaves ``out`` as it was and no temporary. A write
    that fails is one line: WriteError (disk full, read-only, too large: `WRITE_ERRNOS`) or
    StoreError. ``stage`` names the write for `save_stage`. (Branch files: `write_h5`.)"""
    out = Path(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        _replace(out, write, stage)
    except OSError as exc:
        raise _cannot_write(out, exc) from exc
    return out


def is_stream(out: Path) -> bool:
    """Whether ``out`` is a stream an export writes in place, appending: a path in /dev
    (``/dev/stdout``, even when the shell redirects it to a file) or one that is no regular
    file (a pipe, a terminal, a link to one). A rename over it would replace the device's
    link with a file (as root, ``/dev/stdout`` itself), and opening it anew for writing would
    truncate a file redirected to with ``>>``: appending is right for ``>`` and ``>>``."""
    return Path("/dev") in out.absolute().parents or out.exists() and not out.is_file()


def export_csv(bf: BranchFile, out: Path):
    """Every point of every branch, one row each (header: branch,pt,type,label,<parameters>,
    <ordinates>,index,index_rule,index_direct). Floats are written with 17 significant digits.

    The CSV is written to a temporary file beside ``out`` and renamed over it, so a failed
    export leaves ``out`` as it was; a stream (`is_stream`) is appended to in place.
    StoreError if ``out`` is the branch file itself or cannot be written."""
    header = export_names(bf.parameters, bf.ordinates)
    out = Path(out)
    if same_file(bf.path, out):
        raise StoreError(f"{out} is the branch file being exported ({bf.path}); "
                         "choose another name for the CSV")
    def write(tmp, mode="w"):
        with open(tmp, mode, newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            for row in rows(bf):
                w.writerow([repr(row[h]) if isinstance(row[h], float) else row[h]
                            for h in header])

    if is_stream(out):
        try:
            write(out, "a")
        except OSError as exc:
            raise _cannot_write(out, exc) from exc
        return out
    return write_atomically(out, write)

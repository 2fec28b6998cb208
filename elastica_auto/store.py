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
        profiles            (points, states, grid): every state on /profile_grid
        solutions/<LAB>/    s, y, yp: the exact collocation solution of a labelled point;
                            tangent_s, tangent_y, tangent_yp and attr tangent_lam; attrs
                            params (JSON) and pt

    /snaps/                 snap-back targets, one row per (LP, stable equilibrium at its
                            parameters): lp, branch, parameter, value, stable_side, k,
                            index, target_<ordinate>..., on_branch (0: no computed branch);
                            profiles (targets, states, grid): each target on /profile_grid

Files are written to a temporary name in the same folder, then renamed over the target, so a
reader never sees a half-written file.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import h5py
import numpy as np

from . import FORMAT_VERSION, __version__
from .branch import INDEX_UNKNOWN, PROFILE_GRID, Branch
from .errors import StoreError
from .solution import State, Tangent

FORMAT = "elastica-auto"


def _ordinate_for(problem, parameter):
    return next((o.name for o in problem.ordinates.values() if o.parameter == parameter), "")


def _tex_labels(problem) -> dict[str, str]:
    """Math-mode TeX label of every parameter and ordinate, for plots."""
    out = {}
    for name, obj in [*problem.parameters.items(), *problem.ordinates.items()]:
        out[name] = obj.tex if obj.tex.startswith("$") else f"${obj.tex}$"
    return out


class Writer:
    """Writes a run's branch file after each branch, atomically.

    Each save copies the last complete file to a temporary name in the same folder, appends the
    branches not written yet, and renames it over the target: a reader (or an interrupted run)
    never sees a half-written file, and completed branches are not written twice.
    """

    def __init__(self, path: Path, run: str, problem, run_file_text: str = ""):
        self.path = Path(path)
        self.run, self.problem, self.text = run, problem, run_file_text
        self.written = 0
        self.labels: dict[str, list[int]] = {}

    def save(self, branches: list[Branch], snaps: list[dict] | None = None):
        """Write ``branches`` (labels already numbered); earlier ones are kept as written.
        ``snaps``: the snap-back target table (replaces any stored one)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp",
                                   dir=self.path.parent)
        os.close(fd)
        try:
            if self.written:
                shutil.copyfile(self.path, tmp)
            with h5py.File(tmp, "a" if self.written else "w") as f:
                if not self.written:
                    self._write_header(f)
                for k in range(self.written + 1, len(branches) + 1):
                    br = branches[k - 1]
                    _write_branch(f.create_group(f"branches/{k:03d}"), self.problem, br)
                    for pt, p in enumerate(br.points, start=1):
                        if p.type:
                            self.labels[p.name] = [k, pt]
                f.attrs["labels"] = json.dumps(self.labels)
                if snaps is not None:
                    _write_snaps(f, snaps)
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        self.written = len(branches)

    def _write_header(self, f):
        problem = self.problem
        f.attrs.update(format=FORMAT, format_version=FORMAT_VERSION, run=self.run,
                       equation=problem.source, version=__version__,
                       created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                       run_file=self.text, states=json.dumps(problem.states),
                       parameters=json.dumps(problem.parameter_names),
                       ordinates=json.dumps(problem.ordinate_names),
                       tex=json.dumps(_tex_labels(problem)),
                       periods=json.dumps({k: q.period for k, q in problem.parameters.items()
                                           if q.period is not None}))
        f["profile_grid"] = PROFILE_GRID


def _write_snaps(f, snaps: list[dict]):
    """/snaps: one row per (LP, stable target); numbers as float columns, names as strings."""
    if "snaps" in f:
        del f["snaps"]
    g = f.create_group("snaps")
    keys = [k for k in snaps[0] if k != "profile"] if snaps else []
    g.attrs["columns"] = json.dumps(keys)
    if snaps:
        g["profiles"] = np.array([row["profile"] for row in snaps])
    for k in keys:
        values = [row[k] for row in snaps]
        if isinstance(values[0], str):
            g.create_dataset(k, data=values, dtype=h5py.string_dtype())
        else:
            g[k] = np.asarray(values, dtype=float)


def _write_branch(g, problem, br: Branch):
    g.attrs.update(parameter=br.parameter, ordinate=_ordinate_for(problem, br.parameter),
                   direction=br.direction, start=br.start, options=json.dumps(br.options),
                   end=br.end, message=br.message, diagnostics=json.dumps(br.diagnostics),
                   warnings=json.dumps(br.warnings), seconds=br.seconds)
    cols = g.create_group("columns")
    for name in problem.parameter_names + problem.ordinate_names:
        cols[name] = br.column(name).astype(float)
    for name in ("arclength", "ds", "fold_residual"):
        cols[name] = br.column(name).astype(float)
    for name in ("niter", "nodes", "label", "index", "index_rule", "index_direct"):
        cols[name] = br.column(name).astype(np.int32)
    str_dt = h5py.string_dtype()
    cols.create_dataset("type", data=[p.type for p in br.points], dtype=str_dt)
    cols.create_dataset("note", data=[p.note for p in br.points], dtype=str_dt)
    cols.create_dataset("transition", data=[br.transition(p) if p.type in ("LP", "BP") else ""
                                            for p in br.points], dtype=str_dt)
    g["profiles"] = np.array([p.profile for p in br.points])
    sols = g.create_group("solutions")
    for pt, p in enumerate(br.points, start=1):
        if not p.type:
            continue
        h = sols.create_group(p.name)
        h.attrs.update(params=json.dumps(p.params), pt=pt)
        h["s"], h["y"], h["yp"] = p.state.s, p.state.y, p.state.yp
        if p.tangent is not None:
            h["tangent_s"], h["tangent_y"], h["tangent_yp"] = p.tangent.s, p.tangent.y, p.tangent.yp
            h.attrs["tangent_lam"] = p.tangent.lam
            h.attrs["tangent_parameter"] = br.parameter


@dataclass
class StoredBranch:
    """A branch read back from a file: attributes and columns (``b.columns["psi"]``)."""

    number: int
    attrs: dict
    columns: dict[str, np.ndarray]
    profiles: np.ndarray

    @property
    def parameter(self) -> str:
        return self.attrs["parameter"]

    def __len__(self):
        return len(self.columns["type"])

    def label_names(self) -> list[str]:
        return [f"{t}{n}" if t else "" for t, n in zip(self.columns["type"], self.columns["label"])]


@dataclass
class StoredLabel:
    """A labelled point: its solution (a restart point) and, if stored, its tangent."""

    name: str
    branch: int
    pt: int
    state: State
    tangent: Tangent | None
    tangent_parameter: str | None


class BranchFile:
    """A read-only view of an elastica-auto HDF5 file; raises StoreError with one line."""

    def __init__(self, path):
        self.path = Path(path)
        if not self.path.is_file():
            raise StoreError(f"{self.path}: no such file")
        try:
            with h5py.File(self.path, "r") as f:
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
                self.labels = {k: tuple(v) for k, v in json.loads(self.attrs["labels"]).items()}
                self.profile_grid = f["profile_grid"][()]
                self.snaps = []
                if "snaps" in f:
                    keys = json.loads(f["snaps"].attrs["columns"])
                    cols = {k: [x.decode() if isinstance(x, bytes) else x
                                for x in f["snaps"][k][()]] for k in keys}
                    self.snaps = [dict(zip(keys, vals)) for vals in zip(*cols.values())]
                    if "profiles" in f["snaps"]:
                        for row, prof in zip(self.snaps, f["snaps/profiles"][()]):
                            row["profile"] = prof
                self.branches = []
                for key in sorted(f.get("branches", {})):
                    g = f["branches"][key]
                    cols = {}
                    for name, ds in g["columns"].items():
                        data = ds[()]
                        if ds.dtype.kind == "O":
                            data = np.array([x.decode() if isinstance(x, bytes) else x
                                             for x in data], dtype=object)
                        cols[name] = data
                    self.branches.append(StoredBranch(int(key), dict(g.attrs), cols,
                                                      g["profiles"][()]))
        except StoreError:
            raise
        except (OSError, KeyError, ValueError) as exc:
            raise StoreError(f"{self.path}: unreadable branch file ({exc})") from exc

    @property
    def run(self) -> str:
        return self.attrs["run"]

    @property
    def equation(self) -> str:
        return self.attrs["equation"]

    def label_ranges(self) -> str:
        """The labels in the file, compactly: ``EP1-EP16, LP1-LP50, UZ1-UZ276``."""
        counts = {}
        for lab in self.labels:
            counts[lab[:2]] = max(counts.get(lab[:2], 0), int(lab[2:]))
        return ", ".join(f"{t}1-{t}{n}" if n > 1 else f"{t}1"
                         for t, n in sorted(counts.items())) or "none"

    def label(self, name: str) -> StoredLabel:
        """The solution stored under a label such as ``UZ3`` (StoreError if there is none)."""
        if name not in self.labels:
            raise StoreError(f"{self.path}: no label {name!r} (labels: {self.label_ranges()})")
        br, pt = self.labels[name]
        with h5py.File(self.path, "r") as f:
            h = f[f"branches/{br:03d}/solutions/{name}"]
            params = json.loads(h.attrs["params"])
            state = State(h["s"][()], h["y"][()], h["yp"][()], params)
            tangent, tpar = None, None
            if "tangent_y" in h:
                tangent = Tangent(h["tangent_s"][()], h["tangent_y"][()], h["tangent_yp"][()],
                                  float(h.attrs["tangent_lam"]))
                tpar = str(h.attrs["tangent_parameter"])
        return StoredLabel(name, br, pt, state, tangent, tpar)




def _fmt(v):
    return "" if v == INDEX_UNKNOWN else str(int(v))


def rows(bf: BranchFile, labelled_only=False):
    """Yield one dict per point: branch, pt, type, label, parameters, ordinates, indices."""
    for b in bf.branches:
        c = b.columns
        names = b.label_names()
        for i in range(len(b)):
            if labelled_only and not c["type"][i]:
                continue
            row = {"branch": b.number, "pt": i + 1, "type": c["type"][i], "label": names[i]}
            for k in bf.parameters + bf.ordinates:
                row[k] = float(c[k][i])
            for k in ("index", "index_rule", "index_direct"):
                row[k] = _fmt(c[k][i])
            yield row


def export_csv(bf: BranchFile, out: Path):
    """Every point of every branch, one row each (header: branch,pt,type,label,<parameters>,
    <ordinates>,index,index_rule,index_direct). Floats are written with 17 significant digits."""
    header = (["branch", "pt", "type", "label"] + bf.parameters + bf.ordinates
              + ["index", "index_rule", "index_direct"])
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row in rows(bf):
            w.writerow([repr(row[h]) if isinstance(row[h], float) else row[h] for h in header])
    return out

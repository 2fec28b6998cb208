"""AUTO-07p's side of `make bench-auto`: build it from a local copy of its source, compile a
demo's equations against it, run the demo's steps as whole processes and read its labels.

AUTO-07p is a benchmark dependency only: nothing here is imported by the package or the tests,
and no file of AUTO's is in the repository. The source folder (AUTO_SRC) is copied into a
build folder (default ``build/auto-07p``, ignored by git), configured without its plotting
programs, GUI, OpenMP and MPI (``--disable-plaut --disable-plaut04 --disable-gui
--without-openmp --without-mpi``) and its library built with its default compiler flags
(gfortran ``-g -O``). A demo is compiled as AUTO's own command ``@r`` would (the demo's
``.f90`` linked with the library's objects) and run as AUTO's command-line runs do: the
constants file on standard input, a restart read from ``fort.3``, the results written to
``fort.7`` (the branch) and ``fort.8`` (the labelled solutions). AUTO's Python front end is
not used: its start-up (a Python interpreter of its own) is not AUTO's computing.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

CONFIGURE = ("--disable-plaut", "--disable-plaut04", "--disable-gui", "--without-openmp",
             "--without-mpi")


def build(src: Path, dest: Path) -> Path:
    """AUTO-07p built from ``src`` into ``dest`` (once: a stamp file marks a finished build);
    returns ``dest``."""
    stamp = dest / ".built"
    if stamp.exists():
        return dest
    if not (src / "src" / "main.f90").exists():
        raise SystemExit(f"bench-auto: error: {src} is not AUTO-07p's source (no src/main.f90)")
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(src, dest, ignore=shutil.ignore_patterns(".git"))
    for cmd in (["./configure", *CONFIGURE], ["make", "src"]):
        done = subprocess.run(cmd, cwd=dest, capture_output=True, text=True)
        if done.returncode:
            raise SystemExit(f"bench-auto: error: {' '.join(cmd)} failed in {dest}:\n"
                             f"{done.stdout[-2000:]}{done.stderr[-2000:]}")
    stamp.touch()
    return dest


def compile_demo(auto: Path, demo: str, work: Path) -> Path:
    """The demo's folder copied to ``work/demo`` with its executable ``demo.exe`` (the demo's
    equations compiled and linked with AUTO's library objects, as ``@r`` does)."""
    folder = (work / demo).resolve()
    exe = folder / f"{demo}.exe"
    if exe.exists():
        return folder
    if folder.exists():
        shutil.rmtree(folder)
    shutil.copytree(auto / "demos" / demo, folder)
    objects = sorted(str(p) for p in (auto.resolve() / "lib").glob("*.o"))
    for cmd in (["gfortran", "-g", "-O", "-c", f"{demo}.f90", "-o", f"{demo}.o"],
                ["gfortran", "-g", "-O", f"{demo}.o", "-o", exe.name, *objects]):
        subprocess.run(cmd, cwd=folder, check=True, capture_output=True)
    return folder


@dataclass
class Step:
    """One run of a demo's script: its constants file, keywords that replace the file's
    (a later line of a constants file overrides an earlier one), and whether it restarts from
    the previous step's solutions (``IRS`` then names the label, as in the demo's script)."""
    constants: str
    set: dict = field(default_factory=dict)
    restart: bool = False


@dataclass
class Label:
    """A labelled point of AUTO's output: its type ("LP", "BP", ...), label number and its
    parameter values PAR(1..NPAR) as written in fort.8 (11 significant digits)."""
    type: str
    lab: int
    par: list


#: AUTO's point types (fort.7/fort.8 ITP modulo 10 for BVPs)
TYPES = {1: "BP", 2: "LP", 3: "HB", 4: "UZ", 9: "EP", -4: "UZ", -9: "MX", 5: "LP", 6: "BP",
         7: "PD", 8: "TR"}


#: AUTO's converged reference: the mesh refined 8 times, Newton's and the special points'
#: tolerances tightened, and room for 10 times the points (the tighter Newton tolerance
#: shortens AUTO's steps: at NMX its branch would end before the folds). A demo may replace
#: some (`run`'s ``fine``): kar's run ends MX before its third fold at EPSS = 1e-8
FINE = {"EPSL": 1e-10, "EPSU": 1e-10, "EPSS": 1e-8}
FINE_NTST = 8
FINE_NMX = 10


def constants(folder: Path, step: Step, fine: bool | dict = False) -> str:
    """The step's constants file: the demo's, then the step's keywords (a later line
    overrides an earlier one); with ``fine``, AUTO's converged reference settings (`FINE`,
    updated by ``fine`` if it is a dict)."""
    text = (folder / f"c.{step.constants}").read_text()
    keywords = dict(step.set)
    if fine:
        ntst = re.findall(r"\bNTST\s*=\s*(\d+)", text)[-1]
        nmx = re.findall(r"\bNMX\s*=\s*(\d+)", text)[-1]
        keywords = {**keywords, "NTST": FINE_NTST * int(keywords.get("NTST", ntst)),
                    "NMX": FINE_NMX * int(keywords.get("NMX", nmx)), **FINE,
                    **(fine if isinstance(fine, dict) else {})}
    return text + "".join(f"\n{k} = {v!r}" if isinstance(v, str) else f"\n{k} = {v}"
                          for k, v in keywords.items()) + "\n"


def run(folder: Path, demo: str, steps: list[Step], fine: bool | dict = False):
    """Run the demo's steps in turn, each a fresh process of its executable; returns (wall
    seconds of the processes, the points each step computed, labels of every step).
    ``fine``: AUTO's converged reference (`constants`)."""
    folder = folder.resolve()
    exe = str(folder / f"{demo}.exe")
    seconds = 0.0
    points = []
    labels: list[Label] = []
    previous = None
    for step in steps:
        text = constants(folder, step, fine)
        for name in ("fort.7", "fort.8", "fort.9", "fort.3"):
            (folder / name).unlink(missing_ok=True)
        if step.restart:
            (folder / "fort.3").write_text(previous)
        t0 = time.perf_counter()
        done = subprocess.run([exe], input=text, cwd=folder, capture_output=True, text=True)
        seconds += time.perf_counter() - t0
        if done.returncode:
            raise RuntimeError(f"AUTO's {demo} ({step.constants}) failed: {done.stderr[-500:]}")
        points.append(_points(folder / "fort.7"))
        previous = (folder / "fort.8").read_text()
        labels += read_labels(previous)
    return seconds, points, labels


def _points(fort7: Path) -> int:
    """Points of the branch in fort.7 (the rows with a point number; a restart's first point,
    its start, is counted again as AUTO prints it)."""
    n = 0
    for line in fort7.read_text().splitlines():
        parts = line.split()
        if len(parts) > 3 and re.fullmatch(r"-?\d+", parts[0]) and parts[0] != "0":
            n += 1
    return n


def read_labels(fort8: str) -> list[Label]:
    """The labelled solutions of a fort.8 text: each block's header (16 integers: branch,
    point, type, label, NFPR, ISW, NTPL, NAR, NROWPR, NTST, NCOL, NPAR, ...) then NROWPR lines,
    the last of which hold PAR(1..NPAR)."""
    lines = fort8.splitlines()
    out = []
    i = 0
    while i < len(lines):
        head = [int(v) for v in lines[i].split()]
        nrow, npar = head[8], head[11]
        block = lines[i + 1:i + 1 + nrow]
        values = [float(v.replace("D", "E")) for line in block for v in line.split()]
        out.append(Label(TYPES.get(head[2] % 10 if head[2] > 0 else head[2], str(head[2])),
                         head[3], values[-npar:]))
        i += 1 + nrow
    return out

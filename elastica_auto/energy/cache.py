"""The generated modules on disk, keyed by what they were derived from.

The folder is ``$XDG_CACHE_HOME/elastica-auto`` (``~/.cache/elastica-auto`` where that is not
set). It holds

* ``energy-<E>.py``: a generated module (plain numpy source, readable), where E digests the
  energy's expressions (their ``srepr``, names and assumptions included, and every
  parameter's declaration), the generator (the source of this package and elastica-auto's
  version) and sympy's version;
* ``text-<T>``: one line, the E of the module whose text digests (with the generator and
  sympy's version) to T.

A load looks up T first: a module whose file has not changed loads its generated code
without calling ``ENERGY()``, so without importing sympy. Where the text changed (a comment,
a hand-written hook) ``ENERGY()`` is called, and the code is derived again only if the
expressions changed too. Files are written atomically (a temporary file renamed over the
name), so a reader never sees half a module; a folder that cannot be written only costs
the derivation next time. ``ELASTICA_AUTO_ENERGY_CACHE=off`` (or ``0``), or
``load_problem(..., cache=False)``, bypasses the cache: every load derives, nothing is
read or written.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import re
import tempfile
from pathlib import Path

#: The environment variable that switches the cache off ("off", "0", "no", "false").
ENV = "ELASTICA_AUTO_ENERGY_CACHE"


def enabled(cache: bool = True) -> bool:
    """Whether the cache is used: ``cache`` and the environment variable both allow it."""
    return bool(cache) and os.environ.get(ENV, "").strip().lower() not in ("off", "0", "no",
                                                                         "false")


def folder() -> Path:
    """The cache folder (not created here)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "elastica-auto"


@functools.lru_cache(maxsize=1)
def sympy_version() -> str:
    """sympy's version, read from its ``release.py`` without importing it ("none" if it is
    not installed: then a module that misses the cache cannot be derived)."""
    spec = importlib.util.find_spec("sympy")
    if spec is None or not spec.submodule_search_locations:
        return "none"
    for where in spec.submodule_search_locations:
        try:
            text = (Path(where) / "release.py").read_text(encoding="utf-8")
        except OSError:
            continue
        found = re.search(r"__version__\s*=\s*['\"]([^'\"]+)['\"]", text)
        if found:
            return found.group(1)
    return "unknown"


@functools.lru_cache(maxsize=1)
def generator() -> str:
    """A digest of what generates the code: this package's source and elastica-auto's
    version (a changed derivation or printer must not reuse old code)."""
    from .. import __version__
    digest = hashlib.sha256(__version__.encode())
    for path in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _key(*parts: str) -> str:
    digest = hashlib.sha256()
    for part in (generator(), sympy_version(), *parts):
        digest.update(part.encode("utf-8", "surrogatepass") + b"\0")
    return digest.hexdigest()[:32]


def text_key(text: str) -> str:
    """T of a module's source text."""
    return _key("text", text)


def energy_key(canonical: str) -> str:
    """E of an energy's canonical text (`elastica_auto.energy.loader.canonical`)."""
    return _key("energy", canonical)


def _read(path: Path) -> str | None:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None


def code_path(ekey: str) -> Path:
    return folder() / f"energy-{ekey}.py"


def lookup_text(tkey: str) -> tuple[str, Path] | None:
    """The generated code (and its file) of the module text with key T, or None."""
    ekey = _read(folder() / f"text-{tkey}")
    if ekey is None or not re.fullmatch(r"[0-9a-f]{32}", ekey.strip()):
        return None
    return lookup_energy(ekey.strip())


def lookup_energy(ekey: str) -> tuple[str, Path] | None:
    """The generated code (and its file) of the energy with key E, or None."""
    from .runtime import TRAILER
    path = code_path(ekey)
    code = _read(path)
    if code is None or not code.endswith(TRAILER + "\n"):
        return None                      # missing, or cut short: derived again
    return code, path


def write_text(path: Path, text: str) -> bool:
    """Write ``text`` to ``path`` atomically; False (nothing written) where it cannot."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError:
        return False
    return True


def store(tkey: str, ekey: str, code: str | None) -> Path | None:
    """Keep ``code`` as the generated module of E (unless None: already there) and T -> E.
    The code's path, or None where the folder cannot be written."""
    path = code_path(ekey)
    if code is not None and not write_text(path, code):
        return None
    write_text(folder() / f"text-{tkey}", ekey + "\n")
    return path

"""How energy modules load (issue 47 items 1, 3-5, 8; elastica_auto/energy, docs/energy.md): the
cache of generated code (a warm load imports no sympy; a worker never derives), the switch
that bypasses it, ``elastica-auto derive`` (the printed module loads and gives the same
results), bad energies (one line, exit status 2), what a module defines by hand taking
precedence (a symmetry hook's zero mode in the derived second variation included), and the
derived gradient flow.
"""

from __future__ import annotations

import math
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.core.errors import EXIT_USER, ProblemError
from elastica_auto.energy import cache as energy_cache
from elastica_auto.model.second_variation import as_second_variation
from elastica_auto.numerics import stability
from elastica_auto.energy.loader import execute
from helpers import EXAMPLES, REFERENCE, REPO, run_cli
from form_reference import Form, dense_count


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    """Each test's generated code in a folder of its own, not the user's cache."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv(energy_cache.ENV, raising=False)
    return tmp_path / "cache" / "elastica-auto"


def write(tmp_path, name, text) -> Path:
    path = tmp_path / f"{name}.py"
    path.write_text(textwrap.dedent(text))
    return path


def python(code, env_cache, *, extra_env=None):
    """Run ``code`` in a fresh interpreter with the cache in ``env_cache``; its stdout."""
    import os
    env = {**os.environ, "XDG_CACHE_HOME": str(env_cache)}
    env.pop(energy_cache.ENV, None)
    env.update(extra_env or {})
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                         text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout


# ---- the cache ---------------------------------------------------------------------------

WARM = """
    import sys
    import elastica_auto as ea
    problem = ea.load_problem({path!r})
    print("sympy" in sys.modules, problem.states)
"""


def test_a_warm_load_does_not_import_sympy(tmp_path, own_cache):
    """Issue 47 item 4: the first load derives (sympy imported) and writes the generated
    module; the next, in another process, reads it and never imports sympy."""
    path = EXAMPLES / "heavy_column.py"
    cold = python(WARM.format(path=str(path)), tmp_path / "cache")
    assert cold.split()[0] == "True"
    assert len(list(own_cache.glob("energy-*.py"))) == 1
    warm = python(WARM.format(path=str(path)), tmp_path / "cache")
    assert warm.split()[0] == "False" and warm == cold.replace("True", "False", 1)


RUN = """
    import sys
    from click.testing import CliRunner
    from elastica_auto.cli import main
    result = CliRunner().invoke(main, ["run", {run!r}, "--out", {out!r}, "-q"])
    assert result.exit_code == 0, result.output
    print(*(name in sys.modules for name in {names!r}))
"""


def test_a_warm_run_imports_only_what_it_uses(tmp_path, own_cache):
    """Issue 50 (start-up): a one-branch run of an energy-first module given by its path
    (examples/bratu.toml), its cache warm, imports neither sympy nor what only other runs
    need: importlib.resources (shipped runs and modules), the socket module (the lock file's
    host is os.uname's), the energy's declarations (elastica_auto.energy.declare: a
    derivation's), distributed (a cluster's), scipy.integrate (snap-back scans)."""
    names = ["sympy", "importlib.resources", "socket", "elastica_auto.energy.declare",
             "distributed", "scipy.integrate"]
    code = RUN.format(run=str(EXAMPLES / "bratu.toml"), out=str(tmp_path / "out"), names=names)
    python(code, tmp_path / "cache")                 # the cache filled (a derivation)
    warm = python(code, tmp_path / "cache")
    assert dict(zip(names, warm.split())) == dict.fromkeys(names, "False")


def test_a_changed_text_with_the_same_energy_reuses_the_code(tmp_path, own_cache):
    """A module edited outside its energy (a comment) calls ENERGY() again but finds the code
    of the same expressions: nothing is derived (derive is broken to show it)."""
    path = write(tmp_path, "heavy", (EXAMPLES / "heavy_column.py").read_text())
    ea.load_problem(path)
    path.write_text(path.read_text() + "\n# a comment\n")
    out = python(f"""
        import elastica_auto.energy.derive as d
        def refuse(energy):
            raise AssertionError("derived again")
        d.derive = refuse
        import elastica_auto as ea
        print(ea.load_problem({str(path)!r}).states)
        """, tmp_path / "cache")
    assert "theta" in out
    assert len(list(own_cache.glob("energy-*.py"))) == 1
    assert len(list(own_cache.glob("text-*"))) == 2


def test_the_switch_bypasses_the_cache(tmp_path, own_cache, monkeypatch):
    """load_problem(..., cache=False) and ELASTICA_AUTO_ENERGY_CACHE=off derive afresh and
    write nothing."""
    path = EXAMPLES / "heavy_column.py"
    ea.load_problem(path, cache=False)
    assert not own_cache.exists()
    monkeypatch.setenv(energy_cache.ENV, "off")
    ea.load_problem(path)
    assert not own_cache.exists()
    monkeypatch.delenv(energy_cache.ENV)
    ea.load_problem(path)
    assert len(list(own_cache.glob("energy-*.py"))) == 1


def test_a_damaged_cache_file_is_derived_again(tmp_path, own_cache):
    path = EXAMPLES / "heavy_column.py"
    ea.load_problem(path)
    (code,) = own_cache.glob("energy-*.py")
    code.write_text(code.read_text()[:500])           # cut short
    problem = ea.load_problem(path)
    assert problem.rhs(np.linspace(0, 1, 3), np.zeros((2, 3)), {"q": 1.0}).shape == (2, 3)
    assert code.read_text() == problem.generated


def test_a_problem_travels_with_its_generated_code(tmp_path):
    """Issue 47 item 4: pickled (as to a Dask worker), a problem carries the generated module;
    unpickled where sympy cannot be imported and the cache is off, it works: no worker
    derives."""
    problem = ea.load_problem("elastica_lever_arm")
    blob = tmp_path / "problem.pickle"
    blob.write_bytes(pickle.dumps(problem))
    out = python(f"""
        import pickle, sys
        import numpy as np
        sys.modules["sympy"] = None                       # import sympy fails
        problem = pickle.loads(open({str(blob)!r}, "rb").read())
        s = np.linspace(0, 1, 5)
        y = np.full((4, 5), 0.3)
        print(problem.states, float(problem.rhs(s, y, problem.defaults())[1, 0]))
        """, tmp_path / "nocache", extra_env={energy_cache.ENV: "off"})
    s, y = np.linspace(0, 1, 5), np.full((4, 5), 0.3)
    assert out.split(")")[1].strip() == repr(float(problem.rhs(s, y, problem.defaults())[1, 0]))


# ---- elastica-auto derive -----------------------------------------------------------------

@pytest.mark.parametrize("name", ["elastica_lever_arm", "kirchhoff_lever_arm", "elastica_pinned",
                                  "spatial_column", "clamped_column", "bratu",
                                  "foundation_column"])
def test_the_printed_module_loads_and_gives_the_same_results(tmp_path, cli_exe, name):
    """Issue 47 item 5: `derive MODULE.py -o OUT.py` writes a plain module (no ENERGY, its
    hand-written hooks kept) whose functions and ordinates equal the loaded module's, and
    whose header says what was derived."""
    out = tmp_path / "printed.py"
    path = EXAMPLES / f"{name}.py" if (EXAMPLES / f"{name}.py").is_file() else \
        REPO / "equations" / f"{name}.py"
    result = run_cli(cli_exe, "derive", path, "-o", out)
    assert result.returncode == 0, result.stderr
    text = out.read_text()
    assert "def ENERGY" not in text and "# second variation" in text
    assert "# parameters (where each enters" in text
    printed, loaded = ea.load_problem(out), ea.load_problem(path)
    assert printed.generated is None
    assert printed.states == loaded.states and printed.free == loaded.free
    assert list(printed.parameters.values()) == list(loaded.parameters.values())
    assert printed.ordinate_names == loaded.ordinate_names
    rng = np.random.default_rng(0)
    s = np.sort(np.r_[0, rng.uniform(0, 1, 9), 1])
    y = rng.uniform(-1, 1, (loaded.n, 11))
    p = {k: v + 0.1 for k, v in loaded.defaults().items()}
    for fn in ("rhs", "rhs_jac"):
        np.testing.assert_array_equal(getattr(printed, fn)(s, y, p), getattr(loaded, fn)(s, y, p))
    np.testing.assert_array_equal(printed.bc(y[:, 0], y[:, -1], p), loaded.bc(y[:, 0], y[:, -1], p))
    for k in loaded.ordinates:
        assert printed.ordinates[k].fn(s, y, p) == loaded.ordinates[k].fn(s, y, p)
    a = as_second_variation(printed.second_variation(s, y, p), "")
    b = as_second_variation(loaded.second_variation(s, y, p), "")
    for what in ("A", "B", "C", "E0", "E1"):
        np.testing.assert_array_equal(getattr(a, what), getattr(b, what))
    assert (printed.exact_start(s, p) is None) == (loaded.exact_start(s, p) is None)
    if printed.has_gradient_flow:
        nodes = np.linspace(0, 1, 21)
        fa, fb = printed.gradient_flow(p, nodes), loaded.gradient_flow(p, nodes)
        # near a constant field: a frame's neighbouring quaternions less than a half turn
        # apart (the discrete strain is NaN beyond, frame_flow.geometry)
        u = 1 + 0.1 * rng.uniform(-1, 1, len(fa.mass))
        assert np.isfinite(fa.energy(u)) and fa.energy(u) == fb.energy(u)
        np.testing.assert_array_equal(fa.force(u), fb.force(u))


def test_derive_prints_to_stdout_and_refuses_a_module_without_energy(cli_exe, tmp_path):
    result = run_cli(cli_exe, "derive", EXAMPLES / "heavy_column.py")
    assert result.returncode == 0 and "def rhs(s, y, p):" in result.stdout
    # a shipped module by its name, as `run` takes it (its file was read as a path: exit 4)
    result = run_cli(cli_exe, "derive", "elastica_lever_arm")
    assert result.returncode == 0, result.stderr
    assert "def rhs(s, y, p):" in result.stdout
    assert result.stdout == run_cli(cli_exe, "derive", REPO / "equations" /
                                    "elastica_lever_arm.py").stdout
    result = run_cli(cli_exe, "derive", REFERENCE / "bratu.py")
    assert result.returncode == EXIT_USER
    assert result.stderr.strip().splitlines() == [
        f"elastica-auto: error: {REFERENCE / 'bratu.py'}: defines no ENERGY(); there is "
        "nothing to derive"]


# ---- bad input -----------------------------------------------------------------------------

BAD = {
    "not convex": ("density=-t.diff(s)**2/2 + q*sp.cos(t), coordinates=[t], parameters={q: 1.0}",
                   "not strictly convex in theta' (d2L/dtheta'2 = -1 at s = 0, theta = 0"),
    "not convex where theta' = 0": (
        "density=t.diff(s)**4/4 - t.diff(s)**2/2, coordinates=[t], parameters={q: 1.0}, "
        "end1=q*t", "theta' = 0"),
    "no unique inverse": (
        "density=(t.diff(s) + u.diff(s))**2/2 + q*sp.cos(t), coordinates=[t, u], "
        "parameters={q: 1.0}", "no unique inverse"),
    "a name twice": ("density=t.diff(s)**2/2 + q*sp.cos(t), coordinates=[t], "
                     "parameters={q: 1.0, sp.Symbol('q', positive=True): 2.0}",
                     "the name 'q' is used twice"),
    "a coordinate's name as a parameter": (
        "density=t.diff(s)**2/2 + q*sp.cos(t), coordinates=[t], "
        "parameters={q: 1.0, sp.Symbol('theta'): 2.0}", "the name 'theta' is used twice"),
    "the energy's ordinate's name": (
        "density=t.diff(s)**2/2 + E*sp.cos(t), coordinates=[t], parameters={E: 1.0}",
        "the energy's ordinate is named E: rename the parameter"),
    "nowhere": ("density=t.diff(s)**2/2 + q*sp.cos(t), coordinates=[t], "
                "parameters={q: 1.0, r: 2.0}", "the parameter r enters nowhere"),
    "undeclared coordinate": ("density=t.diff(s)**2/2 + q*sp.cos(t), coordinates=[t], "
                              "parameters={q: 1.0}, fixed1={u: 0}",
                              "fixed1: u(s) is not a declared coordinate"),
    "quadrature in the density": (
        "density=t.diff(s)**2/2 + q*x*sp.cos(t), coordinates=[t], parameters={q: 1.0}, "
        "quadratures={x: sp.sin(t)}, fixed0={x: 0}", "pointwise constraint x' = g, which the "
        "engine's form cannot express: make it a coordinate, its rate x' = g then an energy "
        "term (a shear stiffness G (x' - g)^2 / 2"),
    "quadrature nonlinear at the end": (
        "density=t.diff(s)**2/2, coordinates=[t], parameters={q: 1.0}, "
        "quadratures={x: sp.sin(t)}, fixed0={x: 0}, end1=q*x*t",
        "a product of two integrals of h"),
    # hostile round 4: the example in the line named x(0) whatever the quadrature
    "a quadrature without its start": (
        "density=t.diff(s)**2/2 + q*sp.cos(t), coordinates=[t], parameters={q: 1.0}, "
        "quadratures={u: sp.sin(t)}", "the quadrature u has no initial value: give it in "
        "fixed0 ({u: 0} for u(0) = 0)"),
    "constraint without multiplier": (
        "density=t.diff(s)**2/2 + q*sp.cos(t), coordinates=[t], parameters={q: 1.0}, "
        "quadratures={x: sp.sin(t)}, fixed0={x: 0}, fixed1={x: 0}", "name its multiplier"),
    "numpy cannot": ("density=t.diff(s)**2/2 + q*sp.besselj(0, t), coordinates=[t], "
                     "parameters={q: 1.0}", "numpy cannot evaluate the function besselj"),
    "undeclared symbol": ("density=t.diff(s)**2/2 + r*sp.cos(t), coordinates=[t], "
                          "parameters={q: 1.0}", "contains r, not a parameter"),
    # a newcomer's matrix: the two terms as a column, and a quadratic form u.T K u without
    # its [0] (a 1 x 1 matrix; sympy counts a Matrix as an expression, so it got through)
    "a density that is a matrix": (
        "density=sp.Matrix([t.diff(s)**2/2, q*sp.cos(t)]), coordinates=[t], "
        "parameters={q: 1.0}", "the density is a 2 x 1 matrix, not a scalar expression"),
    "an end term that is a 1 x 1 matrix": (
        "density=t.diff(s)**2/2, end1=sp.Matrix([[q]]).T*sp.Matrix([[t]]), coordinates=[t], "
        "parameters={q: 1.0}", "end1 is a 1 x 1 matrix, not a scalar expression: take its "
        "entry, [0]"),
    "second order": ("density=t.diff(s, 2)**2/2 + q*sp.cos(t), coordinates=[t], "
                     "parameters={q: 1.0}", "first derivatives only"),
    # a rotation coordinate (R = Rotation("R"))
    "rotation: not convex in the strains beyond small ones": (
        "density=R.strain.dot(R.strain)/2 - R.strain[0]**4/4 + q*R.d3[2], coordinates=[R], "
        "parameters={q: 1.0}", "not strictly convex in R.u1'"),
    "rotation: not convex in the strains": (
        "density=(R.strain[0]**2 + R.strain[1]**2 - R.strain[2]**2)/2 + q*R.d3[2], "
        "coordinates=[R], parameters={q: 1.0}", "not strictly convex in R.u3'"),
    # hostile round 3: the bending written as |d3'|^2 / 2 vanished without a word (the
    # frame's entries are symbols, constant to sympy's diff(s)), the refusal naming a strain
    # the user never wrote
    "rotation: the frame's entries differentiated": (
        "density=(R.d3.diff(s).T*R.d3.diff(s))[0]/2 + R.strain[2]**2/2 + q*R.d3[2], "
        "coordinates=[R], parameters={q: 1.0}",
        "the density does not contain R.u1: a frame's derivative is written in its strains"),
    "rotation: a strain in an end term": (
        "density=R.strain.dot(R.strain)/2, end1=q*R.strain[0], coordinates=[R], "
        "parameters={q: 1.0}", "end terms depend on the end values only"),
    "rotation: a clamp that is no quaternion": (
        "density=R.strain.dot(R.strain)/2 + q*R.d3[2], coordinates=[R], "
        "parameters={q: 1.0}, fixed0={R: (1, 0, 0)}", "a quaternion, four expressions"),
    "rotation: a clamp in the states": (
        "density=R.strain.dot(R.strain)/2 + q*R.d3[2], coordinates=[R], "
        "parameters={q: 1.0}, fixed0={R: (R.d3[0], 0, 0, 1)}", "the parameters only"),
    "rotation: a name twice": (
        "density=R.strain.dot(R.strain)/2 + q*R.d3[2], coordinates=[R], "
        "parameters={q: 1.0, sp.Symbol('R_q0'): 0.0}", "the name 'R_q0' is used twice"),
    "rotation: the moment's names": (
        "density=R.strain.dot(R.strain)/2 + q*R.d3[2], coordinates=[R], momenta={R: 'm'}, "
        "parameters={q: 1.0}", "a rotation's moment is three states"),
    "rotation: a shifted period": (
        "density=R.strain.dot(R.strain)/2 + q*R.d3[2], coordinates=[R], "
        "parameters={q: Param(1.0, period=1, period_shift={R: 1})}",
        "a period turns its quaternion to -q (period_flip)"),
    "rotation: a constraint's rate with strains, the density not quadratic in them": (
        "density=R.strain.dot(R.strain)/2 + R.strain[0]**4/4 + q*R.d3[2], coordinates=[R], "
        "parameters={q: 1.0, r: 0.0}, quadratures={x: R.strain[0]}, fixed0={x: 0}, "
        "fixed1={x: 0}, multipliers={x: r}",
        "would need the strains' and derivatives' rates (u', zeta'') computed numerically"),
}

BAD_HEAD = """
def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy, Param, Rotation
    s, q, r, E = sp.symbols("s q r E", real=True)
    t, u, x = sp.Function("theta")(s), sp.Function("u")(s), sp.Function("x")(s)
    R = Rotation("R")
    return Energy(s=s, {})
"""


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_energy_is_one_line_and_exit_status_2(tmp_path, cli_exe, case):
    """Issue 47 item 8: each bad energy is refused when it is derived, with one line that
    says what and where (never generated code that fails later)."""
    body, words = BAD[case]
    path = write(tmp_path, "bad", BAD_HEAD.format(body))
    with pytest.raises(ProblemError, match=None) as info:
        ea.load_problem(path)
    assert words in str(info.value) and "\n" not in str(info.value)
    result = run_cli(cli_exe, "derive", path)
    assert result.returncode == EXIT_USER
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("elastica-auto: error: ") and words in line


@pytest.mark.parametrize("extra, words", [
    ("STATES = ('a', 'b')", "cannot define STATES"),
    ("_derived_rhs = None", "_derived_rhs is a name of the generated code"),
])
def test_a_module_cannot_declare_what_the_energy_does(tmp_path, extra, words):
    path = write(tmp_path, "m", (EXAMPLES / "heavy_column.py").read_text() + "\n" + extra + "\n")
    with pytest.raises(ProblemError, match=words):
        ea.load_problem(path)


def test_an_energy_that_fails_is_a_user_error(tmp_path):
    path = write(tmp_path, "m", "def ENERGY():\n    return 1 / 0\n")
    with pytest.raises(ProblemError, match="ENERGY\\(\\) failed: ZeroDivisionError"):
        ea.load_problem(path)
    path = write(tmp_path, "n", "def ENERGY():\n    return 3\n")
    with pytest.raises(ProblemError, match="returned int; expected an elastica_auto.energy"):
        ea.load_problem(path)


def test_user_names_never_reach_the_code_as_identifiers(tmp_path):
    """Names that are Python keywords, numpy's own or the generated code's temporaries, and
    one with quotes and a backslash, load and compute (they appear only as strings)."""
    path = write(tmp_path, "names", '''
        def ENERGY():
            import sympy as sp
            from elastica_auto.energy import Energy, Param
            s = sp.Symbol("s", real=True)
            names = ["lambda", "numpy", "t0", "y0", "p0", 'q"""\\\\x']
            syms = [sp.Symbol(n, real=True) for n in names]
            theta = sp.Function("out")(s)
            density = theta.diff(s)**2 / 2 + sum(a * sp.cos(theta + i) for i, a in enumerate(syms))
            return Energy(density=density, s=s, coordinates=[theta], momenta=["jac"],
                          parameters={a: Param(0.1 * i) for i, a in enumerate(syms)},
                          fixed0={theta: 0})
        ''')
    problem = ea.load_problem(path)
    assert list(problem.parameters)[-1] == 'q"""\\x'
    s = np.linspace(0, 1, 4)
    y = np.full((2, 4), 0.2)
    p = problem.defaults()
    expected = -sum(p[n] * np.sin(0.2 + i) for i, n in enumerate(p))
    np.testing.assert_allclose(problem.rhs(s, y, p)[1], expected, rtol=1e-14)


# ---- precedence ---------------------------------------------------------------------------

def test_hand_written_definitions_take_precedence(tmp_path):
    """A hand-written rhs keeps the derived rhs_jac and rhs_dp out (the engine's differences
    of the hand-written rhs instead); a hand-written distinguished ordinate replaces the
    derived one, a new one is added; exact_start and draw stay the module's."""
    path = write(tmp_path, "m", (EXAMPLES / "heavy_column.py").read_text() + textwrap.dedent('''

        from elastica_auto import Ordinate


        def rhs(s, y, p):
            return np.vstack((y[1], -p["q"] * (1 - s) * np.sin(y[0])))


        def draw(ax, profile, params):
            ax.plot(profile[0])


        ORDINATES = [Ordinate("slope", "slope", lambda s, y, p: y[1, 0], "q"),
                     Ordinate("top", "top", lambda s, y, p: y[0, -1])]
        '''))
    problem = ea.load_problem(path)
    assert problem.module.rhs.__module__ != "elastica_auto_derived_m"
    assert problem._rhs_jac is None and problem._rhs_dp is None
    assert problem._bc_jac is not None and problem.has_second_variation and problem.has_draw
    assert problem.ordinate_names == ["slope", "E", "top"]


# ---- a continuous symmetry ----------------------------------------------------------------

SYMMETRIC = '''
"""Two coordinates turned into each other: E = int (|z'|^2/2 - lam |z|^2/2 + |z|^4/4) ds."""
import numpy as np

from elastica_auto import Symmetry


def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy
    s, lam = sp.symbols("s lam", real=True)
    u, w = sp.Function("u")(s), sp.Function("w")(s)
    r2 = u**2 + w**2
    return Energy(density=(u.diff(s)**2 + w.diff(s)**2) / 2 - lam * r2 / 2 + r2**2 / 4, s=s,
                  coordinates=[u, w], fixed0={u: 0, w: 0}, fixed1={u: 0, w: 0},
                  parameters={lam: 15.0})


def symmetry(s, y, p):
    """The turn of (u, w) (and of the momenta with it); the unfolding is the gradient of
    Noether's conserved u m_w - w m_u."""
    u, w, mu, mw = y
    return Symmetry(np.array([-w, u, -mw, mu]), np.array([mw, -mu, -w, u]))


def guess(s, p):
    """The first mode's amplitude (Galerkin), turned by 0.4 out of the u axis."""
    a = np.sqrt(max(4 * (p["lam"] - np.pi ** 2) / 3, 0.0))
    c, d = np.cos(0.4), np.sin(0.4)
    return np.array([a * c * np.sin(np.pi * s), a * d * np.sin(np.pi * s),
                     a * c * np.pi * np.cos(np.pi * s), a * d * np.pi * np.cos(np.pi * s)])
'''


def test_a_symmetry_hook_works_with_a_derived_module(tmp_path):
    """Issue 47 item 3 for scalar coordinates: a derived module with a hand-written symmetry
    hook is continued on a circle of solutions (phase condition), and its derived second
    variation leaves the generator's zero mode out of the count: the index along the
    circle is the dense count of the form written here (B = (|z|^2 - lam) I + 2 z z^T) on
    the complement of (-w, u), 0 for the first mode; without the zero mode the count is
    not 0 (its zero eigenvalue, refused or counted by the discretisation)."""
    problem = ea.load_problem(write(tmp_path, "o2", SYMMETRIC))
    (br,) = ea.continuation(problem, {"lam": 15.0}, "lam", bounds=(12, 30), directions="+",
                            uz=[17, 20, 24, 28])
    labelled = [p for p in br.points if p.state is not None]
    assert len(labelled) >= 5
    for p in labelled:
        assert "phase condition" in p.note
        form = Form(2, lambda s: np.broadcast_to(np.eye(2), (len(s), 2, 2)),
                    lambda s: _b(p.state(s), p.params["lam"]),
                    G0=np.eye(2), G1=np.eye(2),
                    constraints=[(lambda s: np.stack((-p.state(s)[1], p.state(s)[0]), -1),
                                  np.zeros(2), np.zeros(2))])
        assert p.index_direct == dense_count(form)[0] == 0
    point = br.points[-1]
    state = point.state
    assert stability.count(problem, state).index == 0
    problem.module.second_variation.__globals__["_derived_symmetry"] = None
    assert stability.count(problem, state).index != 0      # the zero mode: -1, or counted


def _b(y, lam):
    z = y[:2].T                                            # (m, 2)
    r2 = np.sum(z * z, axis=1)
    return (r2 - lam)[:, None, None] * np.eye(2) + 2 * z[:, :, None] * z[:, None, :]


# ---- the gradient flow --------------------------------------------------------------------

@pytest.mark.parametrize("name, params, size", [
    ("elastica_lever_arm", {"P": 9 * math.pi ** 2 / 4, "eps": 0.5, "psi": 1.0, "theta0": 0.3},
     40),
    ("foundation_column", {"P": 30.0}, 2 * 41 - 2)])
def test_the_derived_flow_is_the_gradient_of_its_energy(name, params, size):
    """The derived gradient flow (midpoint rule) of the elastica (theta clamped at s = 0)
    and of the foundation column (two coordinates, w held at both ends): force = -grad E /
    mass and its Jacobian against central differences of its energy."""
    problem = ea.load_problem(name if name == "elastica_lever_arm" else EXAMPLES / f"{name}.py")
    p = {**problem.defaults(), **params}
    # the derived flow (the shipped elastica keeps its hand-written one: the paper's landings)
    flow = execute(problem.generated, name).gradient_flow(p, np.linspace(0, 1, 41))
    assert len(flow.mass) == size
    u = 0.3 + np.random.default_rng(1).normal(size=size)
    d = 1e-6
    grad = np.array([(flow.energy(u + d * e) - flow.energy(u - d * e)) / (2 * d)
                     for e in np.eye(size)])
    np.testing.assert_allclose(-flow.mass * flow.force(u), grad,
                               atol=1e-7 * (1 + np.abs(grad).max()))  # the differences' rounding
    jac = np.array([(flow.force(u + d * e) - flow.force(u - d * e)) / (2 * d)
                    for e in np.eye(size)]).T
    np.testing.assert_allclose(flow.jacobian(u).toarray(), jac, atol=1e-4 * np.abs(jac).max())


def test_snaps_land_where_the_hand_written_flow_lands():
    """Where a snap lands (the derived flow and the hand-written one the shipped elastica
    keeps, on the rotating arm at eps = 0.5, P = 9 pi^2/4): the same stable equilibrium from
    every fold, the energy released to the flows' discretisation."""
    shipped = ea.load_problem("elastica_lever_arm")
    derived = execute(shipped.generated, "derived")          # its derived gradient flow
    derived.exact_start, derived.shooting = shipped.module.exact_start, shipped.module.shooting
    out = []
    for problem in (shipped, ea.Problem(derived, "derived")):
        out.append(ea.continuation(problem, {"eps": 0.5, "P": 9 * math.pi ** 2 / 4}, "psi",
                                   directions="both", bounds=(-6 * math.pi, 6 * math.pi),
                                   landing=True).snaps)
    theirs, mine = out
    assert len(mine) == len(theirs) > 10
    assert sum(a["landed"] for a in mine) >= 4
    for a, b in zip(mine, theirs):
        assert (a["lp"], a["landed"], a["on_branch"]) == (b["lp"], b["landed"], b["on_branch"])
        if a["landed"]:
            assert a["energy_released"] == pytest.approx(b["energy_released"], rel=1e-3)


# ---- named parts of the second variation --------------------------------------------------

PARTS = '''
import numpy as np


def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy
    s, P, c = sp.symbols("s P c", real=True)
    u, w = sp.Function("u")(s), sp.Function("w")(s)
    return Energy(density=u.diff(s)**2 / 2 + c * w.diff(s)**2 / 2 + P * (sp.cos(u) + sp.cos(w)),
                  s=s, coordinates=[u, w], fixed0={u: 0, w: 0}, parameters={P: 0.0, c: 4.0},
                  parts={"index_u": [u], "index_w": [w]})


def exact_start(s, p):
    return np.zeros((4, len(s)))
'''


def test_named_parts_are_counted_each_on_its_own(tmp_path):
    """Energy(parts=...) names groups of coordinates: the derived second variation carries
    them and each is an ordinate. Two uncoupled clamped-free columns of stiffness 1 and c =
    4: on the straight state the index of u counts the ((2n - 1) pi / 2)^2 below P, that of
    w the c ((2n - 1) pi / 2)^2, as the engine counts along a branch and the ordinates
    themselves elsewhere."""
    problem = ea.load_problem(write(tmp_path, "parts", PARTS))
    assert problem.ordinate_names[-2:] == ["index_u", "index_w"]
    (br,) = ea.continuation(problem, {"P": 0.0, "c": 4.0}, "P", bounds=(-1, 30), directions="+")
    loads = [((2 * n - 1) * math.pi / 2) ** 2 for n in range(1, 4)]
    for p in br.points:
        if p.type in ("LP", "BP"):
            continue
        count_u = sum(c < p.params["P"] for c in loads)
        count_w = sum(4 * c < p.params["P"] for c in loads)
        assert (p.ordinates["index_u"], p.ordinates["index_w"]) == (count_u, count_w)
        assert p.index == count_u + count_w
    end = br.points[-1]
    assert [problem.ordinates[k].fn(end.state.s, end.state.y, end.params)
            for k in ("index_u", "index_w")] == [2, 1]


# ---- a module imported as a Python module -------------------------------------------------

def test_a_shipped_module_imported_plainly_has_its_derived_names(tmp_path):
    """``import elastica_auto.equations.kirchhoff_lever_arm as rod`` (tools/three_d.py, users'
    scripts): the derived names come on first use (`derived_names`), the same functions as
    `load_problem` gives; a name that is neither derived nor the module's is an
    AttributeError; the hand-written helpers that use derived ones (part_counts) work."""
    out = python("""
        import numpy as np
        import elastica_auto.equations.kirchhoff_lever_arm as rod
        import elastica_auto.equations.elastica_lever_arm as planar
        from elastica_auto import load_problem
        problem = load_problem("kirchhoff_lever_arm")
        p = {q.name: q.default for q in rod.PARAMETERS}
        s = np.linspace(0, 1, 7)
        y = np.random.default_rng(0).uniform(-1, 1, (10, 7))
        assert np.array_equal(rod.rhs(s, y, p), problem.rhs(s, y, p))
        assert np.array_equal(rod.rhs_jac(s, y, p), problem.rhs_jac(s, y, p))
        straight = rod.exact_start(s, {**p, "P": 0.0})
        print(rod.part_counts(s, straight, p), planar.STATES)
        try:
            rod.no_such_name
        except AttributeError:
            print("AttributeError")
        """, tmp_path / "cache")
    # the straight rod at the defaults, P = pi^2/4 above the first critical load 1.5992 of
    # eps = 0.25 (docs/kirchhoff.md) about both axes (b2 = 1): one negative mode in each part
    assert out.splitlines() == ["{'index_in': 1, 'index_out': 1} ('theta', 'kappa', 'x', 'y')",
                                "AttributeError"]

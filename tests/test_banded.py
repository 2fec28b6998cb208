"""The compiled banded LU (`elastica_auto.numerics._banded`) against LAPACK's dgbtrf and dense
solves.

`_banded.lu` writes out LAPACK's unblocked banded LU with partial pivoting (dgbtf2) in the
same storage, so on matrices without ties among the pivot candidates it must choose LAPACK's
pivots and produce its factors up to rounding; its solves must solve the dense system (and
its transpose). scipy's LAPACK wrapper is the reference here only: the package does not use it.
"""

import numpy as np
import pytest
from scipy.linalg.lapack import dgbtrf

from elastica_auto.numerics import _banded


def _banded_matrix(rng, n, kl, ku, scale_diagonal=0.0):
    """A random dense matrix with kl sub- and ku superdiagonals, and its band storage
    (N, 2 kl + ku + 1) by columns, entry (r, c) at [c, kl + ku + r - c]."""
    a = rng.standard_normal((n, n)) + scale_diagonal * np.eye(n)
    rows, cols = np.indices((n, n))
    a[(rows - cols > kl) | (cols - rows > ku)] = 0.0
    ab = np.zeros((n, 2 * kl + ku + 1))
    r, c = np.nonzero((rows - cols <= kl) & (cols - rows <= ku))
    ab[c, kl + ku + r - c] = a[r, c]
    return a, ab


@pytest.mark.parametrize("n, kl, ku", [(1, 0, 0), (5, 0, 0), (7, 2, 0), (7, 0, 3), (9, 3, 2),
                                       (4, 6, 5), (40, 10, 9), (200, 14, 13)])
def test_the_banded_lu_is_lapacks_and_solves_the_system(n, kl, ku):
    rng = np.random.default_rng(1000 * n + 10 * kl + ku)
    for _ in range(3):
        a, ab = _banded_matrix(rng, n, kl, ku)
        lu_ref, piv_ref, info_ref = dgbtrf(ab.T.copy(), kl, ku)
        piv = np.empty(n, dtype=np.intp)
        info = _banded.lu(ab, kl, ku, piv)
        assert info == info_ref == 0
        np.testing.assert_array_equal(piv, piv_ref)   # the same row exchanges
        np.testing.assert_allclose(ab.T, lu_ref, rtol=0, atol=1e-12 * np.abs(lu_ref).max())
        for trans, matrix in ((False, a), (True, a.T)):
            b = rng.standard_normal(n)
            x = b.copy()
            _banded.solve(ab, kl, ku, piv, x, trans)
            expected = np.linalg.solve(matrix, b)
            np.testing.assert_allclose(x, expected, rtol=0,
                                       atol=1e-11 * np.abs(expected).max())


def test_an_exactly_zero_pivot_is_reported_and_the_factorisation_continues():
    """LAPACK's convention: info = 1 + the first step whose pivot is exactly 0; the later
    columns are still eliminated (dgbtrf gives the same factors)."""
    rng = np.random.default_rng(7)
    n, kl, ku = 12, 2, 3
    a, ab = _banded_matrix(rng, n, kl, ku)
    ab[4, :] = 0.0               # column 4 empty: singular, the pivot of step 4 exactly 0
    lu_ref, piv_ref, info_ref = dgbtrf(ab.T.copy(), kl, ku)
    piv = np.empty(n, dtype=np.intp)
    info = _banded.lu(ab, kl, ku, piv)
    assert info == info_ref == 5
    np.testing.assert_array_equal(piv, piv_ref)
    np.testing.assert_allclose(ab.T, lu_ref, rtol=0, atol=1e-12 * np.abs(lu_ref).max())


def test_the_kernel_refuses_buffers_of_the_wrong_kind():
    ab = np.zeros((5, 4))
    with pytest.raises(ValueError, match="piv"):
        _banded.lu(ab, 1, 1, np.empty(5, dtype=np.int32))
    with pytest.raises(ValueError, match="whole number of band columns"):
        _banded.lu(ab, 1, 3, np.empty(5, dtype=np.intp))
    with pytest.raises(ValueError, match="ab"):
        _banded.lu(ab.astype(np.float32), 1, 1, np.empty(5, dtype=np.intp))
    with pytest.raises(ValueError, match="b"):
        _banded.solve(ab, 1, 1, np.zeros(5, dtype=np.intp), np.zeros(4), False)
    with pytest.raises(ValueError, match="negative"):
        _banded.lu(ab, -1, 1, np.empty(5, dtype=np.intp))


def test_a_build_without_a_c_compiler_says_what_the_install_needs(tmp_path, monkeypatch):
    """setup.py's build_ext, run as pip's build runs it but with a compiler that fails
    (``CC=/bin/false``, a machine without gcc), ends with the line naming what the install
    needs (a C compiler and Python's headers) and the C file, not only setuptools' "command
    ... returned non-zero exit status 1". The arguments are setup.py's own: the file is run
    with `setuptools.setup` recording them, then its build_ext class builds its extensions."""
    import setuptools
    from setuptools.errors import CCompilerError

    from helpers import REPO

    given = {}
    monkeypatch.setattr(setuptools, "setup", lambda **kw: given.update(kw))
    exec(compile((REPO / "setup.py").read_text(), str(REPO / "setup.py"), "exec"),
         {"__name__": "__main__"})
    dist = setuptools.Distribution({"ext_modules": given["ext_modules"]})
    cmd = given["cmdclass"]["build_ext"](dist)
    cmd.build_temp, cmd.build_lib = str(tmp_path / "temp"), str(tmp_path / "lib")
    cmd.ensure_finalized()
    monkeypatch.setenv("CC", "/bin/false")
    monkeypatch.chdir(REPO)
    with pytest.raises(CCompilerError) as failed:
        cmd.run()
    assert "the install needs a C compiler and Python's headers" in str(failed.value)
    assert "elastica_auto/numerics/_banded.c" in str(failed.value)

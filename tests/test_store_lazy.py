"""Reading branch files lazily (`elastica_auto.storage.store.BranchFile`), and restart files
opened once.

Opening checks the layout from the datasets' shapes and reads only the label columns; a column,
the profiles or a label's solution is read on first use, from a file opened and closed for that
read, and kept. What is read lazily equals what h5py reads from the file. A read of a file that
was damaged, replaced or removed since it was opened raises one StoreError naming the file. A
run file opens each restart file once, however many starts and selectors name it.
"""

from __future__ import annotations

import json
import os
import shutil
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.execution import runfile
from elastica_auto.branches.branch import column_names
from elastica_auto.core.errors import StoreError
from elastica_auto.storage.store import BranchFile
from helpers import EXAMPLES

BRATU = EXAMPLES / "bratu.py"


@pytest.fixture(scope="module")
def bratu_file(tmp_path_factory):
    """Two Bratu branches (60 and 8 points, UZ labels on the first, EP on both), saved."""
    problem = ea.load_problem(str(BRATU))
    branches = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), uz=[1, 2, 3],
                               directions="both", ds=0.05, ds_max=0.5, max_points=60)
    return ea.save(branches, tmp_path_factory.mktemp("lazy") / "bratu.h5")


@pytest.fixture
def copy(bratu_file, tmp_path):
    """A copy of the file, last modified long ago: any change later shows in its time."""
    path = tmp_path / "bratu.h5"
    shutil.copy(bratu_file, path)
    os.utime(path, ns=(10 ** 18, 10 ** 18))
    return path


@pytest.fixture
def reads(monkeypatch):
    """The names of the datasets read from now on, in order: through h5py's datasets, or
    its low-level calls (the store's ``_dataset`` and ``_part``; a ``_part`` of no columns
    reads nothing)."""
    from elastica_auto.storage import store
    names = []
    getitem, dataset, part = h5py.Dataset.__getitem__, store.checked_dataset, store.part_columns

    def counted(self, args, *rest, **kw):
        names.append(self.name)
        return getitem(self, args, *rest, **kw)

    def counted_dataset(g, name, *rest):
        names.append(f"{g.name}/{name}")
        return dataset(g, name, *rest)

    def counted_part(g, name, a, b):
        if (a, b) != (0, 0):
            names.append(f"{g.name}/{name}")
        return part(g, name, a, b)

    monkeypatch.setattr(h5py.Dataset, "__getitem__", counted)
    monkeypatch.setattr(store, "checked_dataset", counted_dataset)
    monkeypatch.setattr(store, "part_columns", counted_part)
    return names


def _eager(path, key: str) -> dict[str, np.ndarray]:
    """Every column of branch ``key`` as h5py reads it, strings decoded."""
    with h5py.File(path, "r") as f:
        out = {}
        for name, ds in f[f"branches/{key}/columns"].items():
            data = ds[()]
            out[name] = (np.array([x.decode() for x in data], dtype=object)
                         if ds.dtype.kind in "OS" else data)   # strings: format 3 / 1, 2
        return out | {"profiles": f[f"branches/{key}/profiles"][()]}


def test_lazy_columns_equal_an_eager_read(bratu_file):
    bf = BranchFile(bratu_file)
    assert [len(b) for b in bf.branches] == [60, 8]
    names = column_names(bf.parameters, bf.ordinates)
    for b in bf.branches:
        eager = _eager(bratu_file, f"{b.number:03d}")
        cols = b.columns
        assert list(cols) == names and len(cols) == len(names) and "nope" not in cols
        assert all(name in cols for name in names) and "profiles" not in cols
        for name in names:
            if name in ("branch", "pt", "label"):
                continue
            assert cols[name].dtype == eager[name].dtype, name
            np.testing.assert_array_equal(cols[name], eager[name], err_msg=name)
        np.testing.assert_array_equal(cols["branch"], np.full(len(b), b.number))
        np.testing.assert_array_equal(cols["pt"], np.arange(1, len(b) + 1))
        made = [f"{t}{k}" if t else "" for t, k in zip(eager["type"], eager["label"])]
        assert list(cols["label"]) == made == b.label_names()
        assert dict(cols.items()).keys() == set(names)
        assert all(v is cols[k] for k, v in zip(cols, cols.values()))  # read once, kept
        np.testing.assert_array_equal(b.profiles, eager["profiles"])
        with pytest.raises(KeyError):
            cols["nope"]
    assert "UZ1" in bf.labels and bf.labels["UZ1"][0] == 1


def test_opening_reads_no_profile_and_only_the_label_columns(bratu_file, reads, monkeypatch):
    bf = BranchFile(bratu_file)
    columns = {name for name in reads if "/columns/" in name}
    assert columns == {f"/branches/{k}/columns/{c}" for k in ("001", "002")
                       for c in ("type", "label")}
    # and the names of the labels whose solutions each branch stores (format 2)
    assert all(("/columns/" in name or name == "/profile_grid"
                or name.endswith("/solutions/label")) for name in reads), reads
    b = bf.branches[0]
    del reads[:]
    lam = b.columns["lam"]
    assert reads == ["/branches/001/columns/lam"]
    assert b.columns["lam"] is lam
    b.columns["type"], b.columns["label"], b.columns["pt"], b.label_names(), len(b)
    assert reads == ["/branches/001/columns/lam"]    # kept, or known from opening
    b.profiles
    b.profiles
    # format 3: the branch's distinct profiles, and the row of each point among them
    assert sorted(reads[1:]) == ["/branches/001/profile_rows", "/branches/001/profiles"]
    del reads[:]
    bf.label("UZ1")
    assert reads and all(name.startswith("/branches/001/solutions/") for name in reads)
    # items() reads every column not read yet, in one opening of the file
    opens, File = [], h5py.File
    monkeypatch.setattr(h5py, "File", lambda *a, **kw: opens.append(a) or File(*a, **kw))
    del reads[:]
    cols = dict(bf.branches[1].columns.items())
    stored = set(cols) - {"branch", "pt", "label", "type"}
    assert len(opens) == 1 and sorted(reads) == sorted(f"/branches/002/columns/{name}"
                                                       for name in stored)


def _one_line(exc_info, path):
    msg = str(exc_info.value)
    assert len(msg.splitlines()) == 1 and str(path) in msg, msg
    return msg


def _truncate(path):
    os.truncate(path, path.stat().st_size // 2)


def _replace(path):
    """A run's save: another complete file renamed over it."""
    tmp = path.with_name("other.h5")
    shutil.copy(path, tmp)
    with h5py.File(tmp, "a") as f:
        f["branches/001/columns/lam"][0] = 42.0
    os.replace(tmp, path)


def _edit(path):
    with h5py.File(path, "a") as f:
        f["branches/001/columns/lam"][0] = 42.0


AFTER_OPENING = {"truncated": (_truncate, "damaged branch file"),
                 "replaced": (_replace, "changed since it was opened"),
                 "edited": (_edit, "changed since it was opened"),
                 "removed": (os.unlink, "no such file (removed since it was opened)")}


@pytest.mark.parametrize("change", sorted(AFTER_OPENING))
def test_a_read_after_the_file_changed_raises_one_line(copy, change):
    edit, needle = AFTER_OPENING[change]
    bf = BranchFile(copy)
    b = bf.branches[0]
    lam = b.columns["lam"]
    edit(copy)
    for read in (lambda: b.columns["u_half"], lambda: b.profiles, lambda: bf.label("UZ1"),
                 lambda: dict(b.columns.items())):
        with pytest.raises(StoreError) as exc_info:
            read()
        assert needle in _one_line(exc_info, copy)
    assert b.columns["lam"] is lam and b.label_names()    # what was read stays readable


def _in_place(path, edit):
    """``edit`` applied to the file's bytes in place, keeping its inode, size and times: a
    change the file's identity does not show, so the read itself must notice it."""
    st = path.stat()
    damaged = path.with_name("damaged.h5")
    shutil.copy(path, damaged)
    with h5py.File(damaged, "a") as f:
        edit(f)
    data = damaged.read_bytes()
    assert len(data) <= st.st_size
    with open(path, "r+b") as fh:
        fh.write(data + bytes(st.st_size - len(data)))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert path.stat().st_size == st.st_size and path.stat().st_ino == st.st_ino


def _delete(f):
    del f["branches/001/columns/u_half"]
    del f["branches/001/profiles"]
    del f["branches/001/solutions/y"]


def _shorten(f):
    for name in ("branches/001/columns/u_half", "branches/001/profiles"):
        data = f[name][:-3]
        del f[name]
        f[name] = data


@pytest.mark.parametrize("edit", [_delete, _shorten])
def test_a_read_of_a_file_damaged_in_place_raises_one_line(copy, edit):
    # room at the end (HDF5 ignores bytes past its end of file): an edit may need a few
    # hundred bytes more, new object headers, and the file must keep its size; the datasets
    # it writes anew are not compressed, as the file's are: up to the file's size more
    with open(copy, "ab") as fh:
        fh.write(bytes(copy.stat().st_size + 4096))
    bf = BranchFile(copy)
    b = bf.branches[0]
    _in_place(copy, edit)
    for read, what in ((lambda: b.columns["u_half"], "branch 001: column 'u_half' unreadable"),
                       (lambda: b.profiles, "branch 001: profiles unreadable")):
        with pytest.raises(StoreError) as exc_info:
            read()
        assert f"damaged branch file: {what}" in _one_line(exc_info, copy)
    if edit is _delete:
        with pytest.raises(StoreError) as exc_info:
            bf.label("UZ1")
        assert "damaged branch file: solution UZ1 unreadable" in _one_line(exc_info, copy)


def test_a_profile_dataset_that_is_a_group_is_damaged(copy):
    with h5py.File(copy, "a") as f:
        del f["branches/002/profiles"]
        f.create_group("branches/002/profiles")
    with pytest.raises(StoreError) as exc_info:
        BranchFile(copy)
    assert "damaged branch file: branch 002: 'profiles' is not a dataset" in _one_line(
        exc_info, copy)


def test_a_run_file_opens_each_restart_file_once(bratu_file, tmp_path, monkeypatch):
    shutil.copy(bratu_file, tmp_path / "bratu.h5")
    (tmp_path / "restart.toml").write_text(textwrap.dedent(f"""\
        equation = "{BRATU}"
        start = ["bratu.h5:UZ1", "./bratu.h5:UZ2", "{tmp_path / 'bratu.h5'}:UZ3",
                 {{ file = "bratu.h5", type = "UZ", limit = 2 }},
                 {{ file = "bratu.h5", type = "EP" }}]
        [continuation]
        parameter = "lam"
        bounds = [-1, 4]
        """))
    opened = []

    def counting(path):
        opened.append(path)
        return BranchFile(path)

    monkeypatch.setattr(runfile, "BranchFile", counting)
    plan = runfile.load(tmp_path / "restart.toml")
    assert len(opened) == 1
    starts = [spec.start.label for spec in plan.branches]
    assert {"UZ1", "UZ2", "UZ3", "EP1"} <= set(starts)


# -- format versions ------------------------------------------------------------------------------

#: Written by the format-1 writer (commit 040d308, a group of six datasets per label): two Bratu
#: branches, lam from 0 both ways (12 and 6 points; EP1, UZ1, UZ2, EP2, EP3, EP4).
FORMAT1 = Path(__file__).parent / "data" / "bratu_format1.h5"
#: Written by the code of format 2 (commit aff23cb): the same Bratu continuation, its labels
#: packed, its datasets contiguous and unfiltered, its strings of variable length.
FORMAT2 = Path(__file__).parent / "data" / "bratu_format2.h5"


def test_a_file_of_format_1_still_reads(tmp_path):
    """Every label's solution and tangent as the file's own groups hold them; a run restarts
    from one of its labels."""
    bf = BranchFile(FORMAT1)
    assert bf.attrs["format_version"] == 1 and [len(b) for b in bf.branches] == [12, 6]
    assert sorted(bf.labels) == ["EP1", "EP2", "EP3", "EP4", "UZ1", "UZ2"]
    with h5py.File(FORMAT1, "r") as f:
        for name, (br, pt) in bf.labels.items():
            h = f[f"branches/{br:03d}/solutions/{name}"]
            label = bf.label(name)
            assert (label.branch, label.pt) == (br, pt)
            for got, key in ((label.state.s, "s"), (label.state.y, "y"),
                             (label.state.yp, "yp")):
                np.testing.assert_array_equal(got, h[key][()])
            assert label.state.params == json.loads(h.attrs["params"])
            assert (label.tangent is None) == ("tangent_y" not in h)
            if label.tangent is not None:
                np.testing.assert_array_equal(label.tangent.y, h["tangent_y"][()])
                assert label.tangent.lam == h.attrs["tangent_lam"]
                assert label.tangent_parameter == h.attrs["tangent_parameter"] == "lam"
    problem = ea.load_problem(str(BRATU))
    (again,) = ea.continuation(problem, bf.label("UZ1"), "lam", bounds=(-1, 4), max_points=5)
    assert again.points[0].params["lam"] == bf.label("UZ1").state.params["lam"]


def test_a_file_of_format_2_still_reads(tmp_path):
    """Issue 45 item 7: format 3 compresses and checksums its datasets; a file of format 2
    (no filters, variable-length strings) reads as h5py reads it, and a run restarts from
    one of its labels, the stored solution checked as any."""
    bf = BranchFile(FORMAT2)
    assert bf.attrs["format_version"] == 2 and [len(b) for b in bf.branches] == [12, 8]
    assert sorted(bf.labels) == ["EP1", "EP2", "EP3", "EP4", "UZ1", "UZ2"]
    with h5py.File(FORMAT2, "r") as f:
        assert not f["branches/001/columns/lam"].fletcher32
        assert f["branches/001/columns/type"].dtype.kind == "O"
        for b in bf.branches:
            key = f"branches/{b.number:03d}"
            np.testing.assert_array_equal(b.profiles, f[f"{key}/profiles"][()])
            assert list(b.columns["type"]) == [x.decode() for x in f[f"{key}/columns/type"][()]]
            np.testing.assert_array_equal(b.columns["lam"], f[f"{key}/columns/lam"][()])
        for name, (br, pt) in bf.labels.items():
            g = f[f"branches/{br:03d}/solutions"]
            k = [x.decode() for x in g["label"][()]].index(name)
            a, z = g["nodes"][k:k + 2]
            label = bf.label(name)
            np.testing.assert_array_equal(label.state.y, g["y"][:, a:z])
            assert label.state.params == json.loads(g["params"][k])
    problem = ea.load_problem(str(BRATU))
    (again,) = ea.continuation(problem, bf.label("UZ2"), "lam", bounds=(-1, 4), max_points=5)
    assert again.points[0].params["lam"] == bf.label("UZ2").state.params["lam"] == 2.0


def test_a_file_packs_its_solutions(bratu_file):
    """A few datasets per branch, whatever its number of labels (formats 2 and 3); each label
    reads back as the continuation computed it (`Branches.label`, in memory), bit for bit."""
    problem = ea.load_problem(str(BRATU))
    branches = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), uz=[1, 2, 3],
                               directions="both", ds=0.05, ds_max=0.5, max_points=60)
    bf = BranchFile(bratu_file)
    assert bf.attrs["format_version"] == ea.FORMAT_VERSION == 3 and len(bf.labels) > 4
    with h5py.File(bratu_file, "r") as f:
        for key in f["branches"]:
            sols = f[f"branches/{key}/solutions"]
            assert all(isinstance(sols[k], h5py.Dataset) for k in sols) and len(sols) == 14
    for name in bf.labels:
        mine, memory = bf.label(name), branches.label(name)
        for a, b in ((mine.state, memory.state), (mine.tangent, memory.tangent)):
            assert (a is None) == (b is None)
            if a is not None:
                for q in ("s", "y", "yp"):
                    np.testing.assert_array_equal(getattr(a, q), getattr(b, q), err_msg=name)
        assert mine.state.params == memory.state.params
        if mine.tangent is not None:
            assert mine.tangent.lam == memory.tangent.lam


def test_a_dataset_made_by_the_low_level_calls_is_h5py_s_own(tmp_path):
    """`store.put` (a branch's numeric datasets, made by h5py's low-level calls): each
    dataset has the type, shape, values, layout and filters of the one h5py's
    ``create_dataset`` makes with the same chunks, shuffle, gzip at DEFLATE_LEVEL and
    Fletcher32 (an empty one: contiguous, no filters), empty and non-contiguous arrays
    included."""
    from elastica_auto.storage.store import DEFLATE_LEVEL, put
    arrays = {"f": np.linspace(0, 1, 7), "i32": np.arange(5, dtype=np.int32),
              "i64": np.arange(3, dtype=np.int64), "empty": np.zeros(0),
              "empty2": np.zeros((4, 0)), "nan": np.array([np.nan, 1.0]),
              "three": np.arange(24.0).reshape(2, 3, 4), "strided": np.arange(20.0)[::3],
              "transposed": np.arange(12.0).reshape(3, 4).T}
    with h5py.File(tmp_path / "x.h5", "w") as f:
        for name, data in arrays.items():
            put(f.require_group("low"), name, data)
            filters = ({"chunks": f[f"low/{name}"].chunks, "shuffle": True, "compression": "gzip",
                        "compression_opts": DEFLATE_LEVEL, "fletcher32": True} if data.size
                       else {})
            f.create_dataset(f"high/{name}", data=data, **filters)
    with h5py.File(tmp_path / "x.h5", "r") as f:
        for name, data in arrays.items():
            high, low = f[f"high/{name}"], f[f"low/{name}"]
            assert (low.dtype, low.shape, low.chunks) == (high.dtype, high.shape, high.chunks)
            assert low.id.get_create_plist().get_layout() == high.id.get_create_plist().get_layout()
            assert (low.compression, low.compression_opts, low.shuffle, low.fletcher32) == \
                (high.compression, high.compression_opts, high.shuffle, high.fletcher32)
            assert low.fletcher32 == bool(data.size)
            np.testing.assert_array_equal(low[()], data)
            np.testing.assert_array_equal(low[()], high[()])


def test_every_dataset_is_compressed_and_checksummed(good_file):
    """Format 3 (hostile M5 a, issue 45 item 7): every dataset with data, the tables' too,
    is stored in chunks through shuffle, gzip and Fletcher32; strings are of fixed length
    (a variable-length string lives in a heap no checksum covers)."""
    seen = []
    with h5py.File(good_file, "r") as f:
        assert f.attrs["format_version"] == 3 and "snaps" in f

        def check(name, obj):
            if isinstance(obj, h5py.Dataset) and obj.size:
                seen.append(name)
                assert (obj.shuffle, obj.compression, obj.fletcher32) == (True, "gzip", True), \
                    name
                assert obj.dtype.kind != "O", name
        f.visititems(check)
    assert any(n.startswith("snaps/") for n in seen) and "profile_grid" in seen


def test_a_solution_repeated_at_a_period_is_stored_once(tmp_path):
    """Issue 45 item 7 (files a user can keep): a branch through several periods of psi
    repeats its points exactly (the engine copies them a period on), and format 3 stores each
    distinct profile and labelled solution once (``profile_rows``, ``mesh``,
    ``tangent_mesh``). What reads back is every point's profile and every label's solution
    and tangent as the continuation computed them, bit for bit; the file holds fewer
    profiles than points and fewer meshes than labels."""
    import math
    problem = ea.load_problem("elastica_lever_arm")
    branches = ea.continuation(problem, {"eps": 0.25, "P": math.pi ** 2 / 4}, "psi",
                               bounds=(-4 * math.pi, 4 * math.pi), directions="both",
                               uz=[math.pi / 6], uz_period=2 * math.pi)
    path = ea.save(branches, tmp_path / "arm.h5")
    bf = BranchFile(path)
    with h5py.File(path, "r") as f:
        stored = [(f[f"branches/{k}/profiles"].shape[0], len(f[f"branches/{k}/profile_rows"]),
                   len(f[f"branches/{k}/solutions/nodes"]) - 1,
                   len(f[f"branches/{k}/solutions/mesh"])) for k in f["branches"]]
    assert all(distinct < points and meshes < labels
               for distinct, points, meshes, labels in stored), stored
    for mine, memory in zip(bf.branches, branches):
        np.testing.assert_array_equal(mine.profiles, [p.profile for p in memory.points])
    for name in bf.labels:
        read, computed = bf.label(name), branches.label(name)
        for a, b in ((read.state, computed.state), (read.tangent, computed.tangent)):
            assert (a is None) == (b is None)
            for q in ("s", "y", "yp") if a is not None else ():
                np.testing.assert_array_equal(getattr(a, q), getattr(b, q), err_msg=name)


def test_some_points_profiles_read_without_the_others(tmp_path, monkeypatch):
    """`StoredBranch.profiles_at` (what a page or a figure reads: its labels' profiles) gives
    ``profiles[rows]`` for any rows (unsorted, repeated, negative), in formats 3 and 2, and
    reads only the stored profiles those rows use, each once: of a branch whose points repeat
    a period on, the distinct ones. A row outside the branch is an IndexError; a point whose
    ``profile_rows`` entry lies outside the stored profiles, a damaged file."""
    import math
    from elastica_auto.storage import store
    problem = ea.load_problem("elastica_lever_arm")
    branches = ea.continuation(problem, {"eps": 0.25, "P": math.pi ** 2 / 4}, "psi",
                               bounds=(-4 * math.pi, 4 * math.pi), max_points=400)
    path = ea.save(branches, tmp_path / "arm.h5")
    with h5py.File(path, "r") as f:
        stored_rows = f["branches/001/profile_rows"][()]
    computed = np.array([p.profile for p in branches[0].points])
    n = len(computed)
    i = int(np.flatnonzero(stored_rows != np.arange(n))[0])    # a point repeating another's
    j = int(np.flatnonzero(stored_rows == stored_rows[i])[0])
    rows = [i, 3, j, 3, -1, 0]
    read = []
    part_rows = store.part_rows

    def counted(g, name, wanted):
        read.append((name, list(wanted)))
        return part_rows(g, name, wanted)
    monkeypatch.setattr(store, "part_rows", counted)
    (b,) = BranchFile(path).branches
    np.testing.assert_array_equal(b.profiles_at(rows), computed[rows])
    assert read == [("profiles", sorted({int(stored_rows[r]) for r in rows}))]
    assert len(read[0][1]) < len({r % n for r in rows})    # i and j share their profile
    np.testing.assert_array_equal(b.profiles_at(2), computed[[2]])
    assert b.profiles_at([]).shape == (0, *computed.shape[1:])
    for outside in ([n], [-n - 1]):
        with pytest.raises(IndexError):
            b.profiles_at(outside)
    (b2,) = BranchFile(FORMAT2).branches[:1]
    with h5py.File(FORMAT2, "r") as f:
        np.testing.assert_array_equal(b2.profiles_at([5, 1, 5]),
                                      f["branches/001/profiles"][()][[5, 1, 5]])
    with h5py.File(path, "r+") as f:
        del f["branches/001/profile_rows"]
        f["branches/001/profile_rows"] = np.where(np.arange(n) == 3, 10 ** 6, stored_rows)
    with pytest.raises(StoreError) as err:
        BranchFile(path).branches[0].profiles_at([3])
    assert "damaged" in str(err.value) and "\n" not in str(err.value)


def test_a_mesh_index_out_of_range_is_damage(copy):
    """A label's ``mesh`` index past the stored solutions reads as a damaged file (one line),
    not as an empty or shifted solution."""
    with h5py.File(copy, "r+") as f:
        mesh = f["branches/001/solutions/mesh"]
        data = mesh[()]
        del f["branches/001/solutions/mesh"]
        f["branches/001/solutions/mesh"] = np.full_like(data, 10 ** 6)
    bf = BranchFile(copy)
    with pytest.raises(StoreError) as err:
        bf.label(next(n for n, (br, _) in bf.labels.items() if br == 1))
    assert "damaged" in str(err.value) and "\n" not in str(err.value)


@pytest.fixture
def checks(monkeypatch, tmp_path):
    """The files whose chunks an opening checks from now on (``checksum_failure``'s calls,
    by file name), with a cache folder of this test's own."""
    from elastica_auto.storage import store
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("ELASTICA_AUTO_CHECKSUMS", raising=False)
    names = []
    check = store.checksum_failure

    def counted(group, where):
        names.append(Path(group.file.filename).name)
        return check(group, where)

    monkeypatch.setattr(store, "checksum_failure", counted)
    return names


def _bratu(tmp_path, name="fresh.h5"):
    problem = ea.load_problem(str(BRATU))
    branches = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), uz=[1],
                               ds=0.05, ds_max=0.5, max_points=20)
    return ea.save(branches, tmp_path / name)


def test_a_file_is_checked_once_as_it_is(tmp_path, checks, monkeypatch):
    """Issue 45 item 7 (reading no slower than before the checksums): a file this program
    wrote opens without the checksum pass (HDF5 made its checksums from the bytes it wrote);
    a copy of it (another file) is checked on its first opening, not on the next;
    ``ELASTICA_AUTO_CHECKSUMS=always`` checks on every opening."""
    path = _bratu(tmp_path)
    BranchFile(path)
    assert checks == []
    copied = tmp_path / "copied.h5"
    shutil.copy(path, copied)
    BranchFile(copied)
    BranchFile(copied)
    assert checks == ["copied.h5"]
    monkeypatch.setenv("ELASTICA_AUTO_CHECKSUMS", "always")
    BranchFile(path)
    BranchFile(path)
    assert checks == ["copied.h5", "fresh.h5", "fresh.h5"]


@pytest.mark.parametrize("times", ["kept", "set back"])
def test_a_known_file_damaged_in_place_is_checked_again(tmp_path, checks, times):
    """Issue 45 item 7: bytes written over a chunk of a file known to match its checksums
    (written by this program, opened since) are found on the next opening, the dataset
    named, even with the file's modification time set back to what it was: a write changes
    the file's status-change time, which no user can set."""
    path = _bratu(tmp_path)
    BranchFile(path)
    before = os.stat(path)
    with h5py.File(path, "r") as f:
        chunk = f["branches/001/columns/lam"].id.get_chunk_info(0)
    with open(path, "r+b") as fh:
        fh.seek(chunk.byte_offset)
        fh.write(bytes(b ^ 0xFF for b in fh.read(8)))
    if times == "set back":
        os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns))
        assert os.stat(path).st_mtime_ns == before.st_mtime_ns
    with pytest.raises(StoreError, match="checksum mismatch in /branches/001/columns/lam"):
        BranchFile(path)
    assert checks == ["fresh.h5"]


def test_an_unwritable_cache_only_costs_the_check(tmp_path, checks, monkeypatch):
    """A cache folder that cannot be made (its parent a file) costs the check on every
    opening, and nothing else: the file opens, its damage would be found."""
    (tmp_path / "blocked").write_text("a file where the cache folder would be")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "blocked"))
    path = _bratu(tmp_path)
    BranchFile(path)
    BranchFile(path)
    assert checks == ["fresh.h5", "fresh.h5"]


def test_the_folder_of_checked_files_stays_small_at_a_small_cost(tmp_path, monkeypatch):
    """The remembered files are pruned to the KEEP most recently used once there are more
    than MAX_ENTRIES, and a write lists the folder only when its entry's digest starts with
    "00" (one in PRUNE_EVERY): listing it at every write once it had grown past
    MAX_ENTRIES (a test suite's 14,000 entries) tripled a small run's time."""
    from elastica_auto.storage import verified
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv("ELASTICA_AUTO_CHECKSUMS", raising=False)
    monkeypatch.setattr(verified, "MAX_ENTRIES", 40)
    monkeypatch.setattr(verified, "KEEP", 10)
    where = verified.folder()
    where.mkdir(parents=True)
    for i in range(45):
        (where / f"{i:02d}").touch()
        os.utime(where / f"{i:02d}", ns=(10 ** 18 + i, 10 ** 18 + i))
    listed, scandir = [], os.scandir
    monkeypatch.setattr(os, "scandir", lambda path: listed.append(path) or scandir(path))
    st = os.stat(where / "00")
    monkeypatch.setattr(verified, "entry_path", lambda st: where / "feed")
    verified.remember(st)
    assert listed == [] and len(list(scandir(where))) == 46
    monkeypatch.setattr(verified, "entry_path", lambda st: where / "00ff")
    verified.remember(st)          # a write in PRUNE_EVERY: the folder is pruned
    assert listed == [where]
    assert {p.name for p in where.iterdir()} == {"feed", "00ff"} | {f"{i:02d}"
                                                                   for i in range(37, 45)}

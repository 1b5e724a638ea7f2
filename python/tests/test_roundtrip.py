"""Every output format written by Complex.write reads back with meshio (and trimesh)."""

import numpy as np
import pytest

import isomesh

meshio = pytest.importorskip("meshio")
trimesh = pytest.importorskip("trimesh")


@pytest.fixture(scope="module")
def torus():
    return isomesh.Problem.preset("torus", edge=0.1).trace().complex()


@pytest.fixture(scope="module")
def circle():
    return isomesh.Problem.preset("circle", edge=0.1).trace().complex()


@pytest.fixture(scope="module")
def sphere3():
    return isomesh.Problem.preset("sphere", m=3, d=4, edge=0.4).trace().complex()


def triangle_count(c):
    """Triangles of the fanned polygons of a surface: sum of (sides - 2)."""
    facets, offsets = c.cells(2)
    return int(np.sum(np.diff(offsets) - 2))


# meshio reads OFF files of triangles only (ours has polygons): OFF is read with trimesh below.
@pytest.mark.parametrize("ext", ["ply", "obj", "stl", "mesh", "vtu"])
def test_surface_reads_back_with_meshio(tmp_path, torus, ext):
    path = tmp_path / f"torus.{ext}"
    torus.write(path)
    m = meshio.read(path)
    tris = sum(len(b.data) for b in m.cells if b.type == "triangle")
    polys = sum(len(b.data) for b in m.cells if b.type != "triangle")
    faces = len(torus.cells(2)[1]) - 1
    if ext in ("stl", "mesh"):
        assert tris == triangle_count(torus)
    else:
        assert tris + polys == faces or tris == triangle_count(torus)
    if ext != "stl":  # STL repeats a point per triangle corner
        assert len(m.points) == len(torus.vertices)
        assert np.allclose(m.points[:, :3], torus.vertices, atol=1e-6)


@pytest.mark.parametrize("ext", ["ply", "obj", "off", "stl"])
def test_surface_with_trimesh(tmp_path, torus, ext):
    path = tmp_path / f"torus.{ext}"
    # trimesh's binary PLY reader takes faces of one size only (the torus has triangles and
    # quads); meshio reads the binary form above, trimesh gets the text form.
    torus.write(path, ascii=(ext == "ply"))
    t = trimesh.load(path, force="mesh", process=True)
    topo = torus.topology
    assert t.is_watertight
    assert t.is_winding_consistent
    assert t.euler_number == topo["euler_characteristic"] == 0


def test_vtu_keeps_all_coordinates(tmp_path):
    c = isomesh.Problem.preset("flat-torus", edge=0.3).trace().complex()
    c.write(tmp_path / "t.vtu")
    m = meshio.read(tmp_path / "t.vtu")
    name = next(k for k in m.point_data if m.point_data[k].shape[1:] == (4,))
    assert np.allclose(m.point_data[name], c.vertices)


# meshio reads no edges from PLY or OBJ files; curves round-trip through .mesh and .vtu.
@pytest.mark.parametrize("ext", ["mesh", "vtu"])
def test_curve_reads_back(tmp_path, circle, ext):
    circle.write(tmp_path / f"c.{ext}")
    m = meshio.read(tmp_path / f"c.{ext}")
    lines = sum(len(b.data) for b in m.cells if b.type == "line")
    assert lines == len(circle.cells(1)[1]) - 1 == circle.topology["cells"][1]


@pytest.mark.parametrize("ext", ["mesh", "vtu"])
def test_solid_reads_back(tmp_path, sphere3, ext):
    sphere3.write(tmp_path / f"s.{ext}")
    m = meshio.read(tmp_path / f"s.{ext}")
    tets = sum(len(b.data) for b in m.cells if b.type == "tetra")
    assert tets == len(sphere3.to_meshio().cells[0].data) > 0


def test_npz_is_the_hasse_diagram(tmp_path, torus):
    torus.write(tmp_path / "t.npz")
    z = np.load(tmp_path / "t.npz")
    assert np.array_equal(z["vertices"], torus.vertices)
    for j in (1, 2):
        facets, offsets = torus.cells(j)
        assert np.array_equal(z[f"cells{j}_facets"], facets)
        assert np.array_equal(z[f"cells{j}_offsets"], offsets)
    assert torus.topology["cells"] == [len(torus.vertices)] + [
        len(torus.cells(j)[1]) - 1 for j in (1, 2)]


@pytest.mark.parametrize("ext", ["csv", "xyz", "txt"])
def test_sample_formats(tmp_path, ext):
    s = isomesh.Problem.preset("torus", edge=0.1).trace()
    s.write(tmp_path / f"s.{ext}")
    pts = np.loadtxt(tmp_path / f"s.{ext}", delimiter="," if ext == "csv" else None,
                     skiprows=1 if ext == "csv" else 0)
    assert np.array_equal(pts, s.points)


def test_to_meshio(torus):
    m = torus.to_meshio()
    assert np.array_equal(m.points, torus.vertices)
    assert m.cells[0].type == "triangle"
    assert len(m.cells[0].data) == triangle_count(torus)
    assert m.cells[0].data.max() < len(m.points)


def test_picture(tmp_path, torus):
    torus.picture(tmp_path / "t.png", 320, 240)
    assert (tmp_path / "t.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

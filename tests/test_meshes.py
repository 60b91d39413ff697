"""Geometry-contract tests for renderloop.scene.meshes (fast, pure numpy)."""

from __future__ import annotations

import numpy as np
import pytest

from renderloop.scene.meshes import (
    Mesh,
    box,
    ellipsoid,
    flower,
    frame_from_axis,
    leaf,
    merge,
    pepper,
    pot,
    tube,
)


def random_axes(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(n, 3))
    extra = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [1e-9, 0, -1], [0.9, 0.1, 0.0]])
    return np.concatenate([axes, extra.astype(float)])


def assert_clean(m: Mesh, min_area: float = 1e-12) -> None:
    assert m.vertices.dtype == np.float64 and m.vertices.ndim == 2 and m.vertices.shape[1] == 3
    assert m.faces.dtype == np.int32 and m.faces.ndim == 2 and m.faces.shape[1] == 3
    assert len(m.faces) > 0
    assert np.all(np.isfinite(m.vertices))
    assert m.faces.min() >= 0 and m.faces.max() < len(m.vertices)
    areas = 0.5 * np.linalg.norm(m.face_normals(), axis=1)
    assert areas.min() > min_area, f"degenerate triangle, min area {areas.min()}"
    if m.uv is not None:
        assert m.uv.shape == (len(m.vertices), 2)
        assert np.all(np.isfinite(m.uv)) and m.uv.min() >= 0.0 and m.uv.max() <= 1.0


def assert_watertight(m: Mesh) -> None:
    """Each directed edge once and its reverse present <=> every edge in exactly two
    consistently oriented faces."""
    f = m.faces.astype(np.int64)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    n = len(m.vertices)
    key = e[:, 0] * n + e[:, 1]
    assert len(np.unique(key)) == len(key), "a directed edge is used twice (inconsistent winding)"
    rev = e[:, 1] * n + e[:, 0]
    assert np.all(np.isin(rev, key)), "open boundary edge"
    assert m.signed_volume() > 0


def default_pepper(**kw) -> Mesh:
    args = dict(center=[0.1, -0.2, 0.9], axis=[0.2, 0.1, -1.0], length=0.09, width=0.08, lobes=4, lobe_depth=0.1)
    args.update(kw)
    return pepper(**args)


# ----------------------------------------------------------------- Mesh / merge

def test_transformed_preserves_area_and_maps_vertices() -> None:
    m = default_pepper()
    rot = frame_from_axis(np.array([0.3, -0.7, 0.2]), twist=1.1)
    t = np.array([1.0, 2.0, -3.0])
    m2 = m.transformed(rot, t)
    np.testing.assert_allclose(m2.vertices, m.vertices @ rot.T + t, atol=1e-15)
    assert m2.area == pytest.approx(m.area, rel=1e-12)
    assert m2.signed_volume() == pytest.approx(m.signed_volume(), rel=1e-9)
    np.testing.assert_array_equal(m2.faces, m.faces)
    assert m2.uv is m.uv or np.array_equal(m2.uv, m.uv)


def test_box_area_volume_and_watertight() -> None:
    m = box([1.0, 2.0, 3.0], [0.1, 0.2, 0.3])
    assert_clean(m)
    assert_watertight(m)
    assert len(m.faces) == 12
    assert m.signed_volume() == pytest.approx(0.1 * 0.2 * 0.3)
    assert m.area == pytest.approx(2 * (0.02 + 0.03 + 0.06))
    np.testing.assert_allclose(m.vertices.min(0), [0.95, 1.9, 2.85])
    np.testing.assert_allclose(m.vertices.max(0), [1.05, 2.1, 3.15])


def test_merge_offsets_indices_and_uv_policy() -> None:
    a, b = box([0, 0, 0], 1.0), box([5, 0, 0], 2.0)
    m = merge([a, b])
    assert len(m.vertices) == 16 and len(m.faces) == 24
    np.testing.assert_array_equal(m.faces[12:], b.faces + 8)
    np.testing.assert_allclose(m.vertices[m.faces[12:]], b.vertices[b.faces])
    assert m.uv is None  # boxes have no uv
    assert m.signed_volume() == pytest.approx(1.0 + 8.0)
    assert_watertight(m)
    p, l = default_pepper(), leaf([0, 0, 0], [1, 0, 0], [0, 0, 1], 0.1, 0.04, 0.0, 0.0)
    pl = merge([p, l])
    assert pl.uv is not None and pl.uv.shape == (len(pl.vertices), 2)
    np.testing.assert_array_equal(pl.uv[len(p.vertices):], l.uv)
    assert merge([p, l, a]).uv is None
    assert len(merge([]).faces) == 0


# ----------------------------------------------------------------- frames

@pytest.mark.parametrize("twist", [0.0, 0.7, -2.5])
def test_frame_from_axis_is_rotation(twist: float) -> None:
    for axis in random_axes(0, 200):
        r = frame_from_axis(axis, twist)
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(r[:, 2], axis / np.linalg.norm(axis), atol=1e-12)


def test_frame_twist_rotates_about_axis() -> None:
    axis = np.array([0.1, 0.2, 0.9])
    r0, r1 = frame_from_axis(axis), frame_from_axis(axis, 0.5)
    assert r0[:, 0] @ r1[:, 0] == pytest.approx(np.cos(0.5))
    assert np.cross(r0[:, 0], r1[:, 0]) @ r0[:, 2] == pytest.approx(np.sin(0.5))
    with pytest.raises(ValueError):
        frame_from_axis(np.zeros(3))


# ----------------------------------------------------------------- tube

def test_tube_watertight_follows_points() -> None:
    pts = np.array([[0, 0, 0], [0, 0, 0.1], [0.02, 0.01, 0.2], [0.05, 0.05, 0.25]])
    radii = np.array([0.006, 0.005, 0.004, 0.003])
    m = tube(pts, radii, sides=10)
    assert_clean(m)
    assert_watertight(m)
    np.testing.assert_allclose(m.vertices[0], pts[0])
    np.testing.assert_allclose(m.vertices[-1], pts[-1])
    rings = m.vertices[1:-1].reshape(len(pts), 10, 3)
    np.testing.assert_allclose(rings.mean(axis=1), pts, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(rings - pts[:, None], axis=2), np.repeat(radii[:, None], 10, 1))
    # a straight cylinder has the analytic volume (polygon cross-section)
    straight = tube(np.array([[0, 0, 0], [0, 0, 1.0]]), 0.1, sides=64)
    assert straight.signed_volume() == pytest.approx(0.5 * 64 * 0.01 * np.sin(2 * np.pi / 64))


def test_tube_no_twist_at_right_angle_bend() -> None:
    # a sharp 90-degree bend and a dense smooth arc: rings stay well formed
    bend = tube(np.array([[0, 0, 0], [0, 0, 0.1], [0.1, 0, 0.1], [0.1, 0.1, 0.1]]), 0.01, sides=8)
    assert_clean(bend, min_area=1e-7)
    assert_watertight(bend)
    s = np.linspace(0, np.pi / 2, 40)
    arc = np.stack([0.1 * (1 - np.cos(s)), np.zeros_like(s), 0.1 * np.sin(s)], axis=1)
    m = tube(arc, 0.01, sides=8, caps=False)
    assert_clean(m)
    rings = m.vertices.reshape(40, 8, 3)
    # side quad edges stay short (a twisting frame would make long diagonals)
    step = np.linalg.norm(rings[1:] - rings[:-1], axis=2)
    assert step.max() < 2.0 * np.linalg.norm(arc[1] - arc[0])


def test_tube_without_caps_and_scalar_radius() -> None:
    m = tube(np.array([[0, 0, 0], [0, 0, 0], [1, 1, 1]]), 0.05, sides=6, caps=False)  # duplicate dropped
    assert_clean(m)
    assert len(m.vertices) == 12 and len(m.faces) == 12
    with pytest.raises(ValueError):
        tube(np.array([[0, 0, 0], [0, 0, 0]]), 0.01)


# ----------------------------------------------------------------- pepper

@pytest.mark.parametrize("lobes,lobe_depth,taper,shoulder", [(4, 0.1, 0.15, 0.25), (3, 0.15, 0.3, 0.35),
                                                            (4, 0.05, 0.0, 0.2), (3, 0.0, 0.1, 0.3)])
def test_pepper_watertight_and_plausible_volume(lobes: int, lobe_depth: float, taper: float,
                                                shoulder: float) -> None:
    length, width = 0.09, 0.075
    m = default_pepper(length=length, width=width, lobes=lobes, lobe_depth=lobe_depth, taper=taper,
                       shoulder=shoulder, twist=0.4)
    assert_clean(m)
    assert_watertight(m)
    ratio = m.signed_volume() / (np.pi * (width / 2) ** 2 * length)
    assert 0.3 < ratio < 1.0


def test_pepper_extent_and_size() -> None:
    rng = np.random.default_rng(7)
    for axis in random_axes(1, 15):
        length, width = rng.uniform(0.05, 0.12), rng.uniform(0.05, 0.09)
        center = rng.uniform(-1, 1, 3)
        m = pepper(center, axis, length, width, int(rng.integers(3, 5)), rng.uniform(0.05, 0.15),
                   twist=rng.uniform(0, 6))
        a = axis / np.linalg.norm(axis)
        rel = m.vertices - center
        h = rel @ a
        assert abs(h.max() - h.min() - length) < 1e-9
        assert abs(h.max() + h.min()) < 1e-9  # centred on center
        assert np.linalg.norm(rel, axis=1).max() <= np.hypot(length / 2, 0.55 * width) + 1e-12
        radial = np.linalg.norm(rel - h[:, None] * a, axis=1)
        assert 0.9 * width <= 2 * radial.max() <= 1.1 * width
        # the stalk end (top) is at -axis: the top pole is near the minimum of h
        assert h[0] < 0 < h[-1]


@pytest.mark.parametrize("lobes", [3, 4])
def test_pepper_lobes_visible(lobes: int) -> None:
    rings, segments, width, depth = 16, 32, 0.08, 0.1
    center, axis = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.3, -1.0])
    m = pepper(center, axis, 0.09, width, lobes, depth, rings=rings, segments=segments)
    a = axis / np.linalg.norm(axis)
    ring = m.vertices[1:-1].reshape(rings, segments, 3)[int(0.7 * rings)] - center
    radial = np.linalg.norm(ring - np.outer(ring @ a, a), axis=1)
    assert radial.max() - radial.min() >= 0.5 * depth * width / 2
    # the dominant angular frequency of the radius is the lobe count
    spectrum = np.abs(np.fft.rfft(radial - radial.mean()))
    assert int(np.argmax(spectrum)) == lobes


def test_pepper_is_deterministic_and_uv_in_range() -> None:
    m1, m2 = default_pepper(twist=0.3), default_pepper(twist=0.3)
    np.testing.assert_array_equal(m1.vertices, m2.vertices)
    assert m1.uv is not None
    assert_clean(m1)
    assert np.ptp(m1.uv[:, 1]) == pytest.approx(1.0)


# ----------------------------------------------------------------- leaf

def test_leaf_flat_shape_orientation_and_uv() -> None:
    base, direction, up = np.array([0.1, 0.2, 0.3]), np.array([1.0, 1.0, 0.2]), np.array([0.0, 0.3, 1.0])
    length, width = 0.1, 0.04
    m = leaf(base, direction, up, length, width, curvature=0.0, fold=0.0, rows=10, cols=6)
    assert_clean(m)
    d = direction / np.linalg.norm(direction)
    n = up - (up @ d) * d
    n /= np.linalg.norm(n)
    rel = m.vertices - base
    assert np.linalg.norm(rel[-1]) == pytest.approx(length, rel=1e-12)  # tip
    lateral = np.linalg.norm(rel - np.outer(rel @ d, d), axis=1)
    assert lateral.max() == pytest.approx(width / 2, rel=1e-9)
    assert np.all(np.abs(rel @ n) < 1e-12)  # flat blade
    normals = m.face_normals()
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    middle = normals[len(normals) // 4: 3 * len(normals) // 4]
    assert np.all(middle @ up > 0)
    np.testing.assert_allclose(normals @ n, 1.0, atol=1e-9)
    # uv: u along, v across with the midrib at 0.5
    assert m.uv[0, 0] == 0.0 and m.uv[-1, 0] == 1.0
    on_rib = np.abs(np.cross(rel, d)).sum(axis=1) < 1e-12
    np.testing.assert_allclose(m.uv[on_rib, 1], 0.5)
    assert m.uv[:, 1].min() == pytest.approx(0.0) and m.uv[:, 1].max() == pytest.approx(1.0)


@pytest.mark.parametrize("curvature,fold,twist", [(5.0, 0.3, 0.0), (10.0, 0.6, 0.8), (-4.0, 0.1, -0.5)])
def test_leaf_bent_folded_twisted(curvature: float, fold: float, twist: float) -> None:
    base, direction, up = np.zeros(3), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    length, width = 0.1, 0.045
    m = leaf(base, direction, up, length, width, curvature, fold, twist)
    assert_clean(m)
    tip = np.linalg.norm(m.vertices[-1] - base)
    assert tip == pytest.approx(length, rel=0.15)
    # curvature > 0 bends the tip below the blade plane (toward -normal)
    assert np.sign(m.vertices[-1, 2]) == -np.sign(curvature)
    # tip is the narrow end: all vertices within the blade's length-by-width envelope
    assert np.linalg.norm(m.vertices - base, axis=1).max() <= np.hypot(length, width / 2) + 1e-12
    if fold > 0 and twist == 0 and curvature > 0:
        # V fold: the leaf edges rise above the midrib at the same station
        rows, nc = 8, 5
        grid = m.vertices[:-1].reshape(rows, nc, 3)
        assert np.all(grid[2:, 0, 2] > grid[2:, nc // 2, 2])
        assert np.all(grid[2:, -1, 2] > grid[2:, nc // 2, 2])


# ----------------------------------------------------------------- flower, pot

@pytest.mark.parametrize("petals", [1, 5, 6, 12])
def test_flower_within_radius_and_facing_normal(petals: int) -> None:
    center, normal, radius = np.array([0.3, 0.1, 1.2]), np.array([0.2, -0.5, 0.8]), 0.012
    m = flower(center, normal, radius, petals)
    assert_clean(m)
    assert np.linalg.norm(m.vertices - center, axis=1).max() <= radius + 1e-15
    nrm = m.face_normals()
    assert np.all(nrm @ normal > 0)


@pytest.mark.parametrize("rb,rt,h", [(0.05, 0.07, 0.12), (0.08, 0.08, 0.2), (0.09, 0.06, 0.1)])
def test_pot_bounds_and_watertight(rb: float, rt: float, h: float) -> None:
    base = np.array([0.5, -0.3, 0.02])
    m = pot(base, rb, rt, h, wall=0.004, segments=24)
    assert_clean(m)
    assert_watertight(m)
    rel = m.vertices - base
    assert np.hypot(rel[:, 0], rel[:, 1]).max() <= rt + 1e-12
    assert rel[:, 2].min() >= -1e-12 and rel[:, 2].max() <= h + 1e-12
    assert rel[:, 2].max() == pytest.approx(h) and rel[:, 2].min() == pytest.approx(0.0)
    # soil disc centre sits 2 cm below the rim and its fan faces up
    np.testing.assert_allclose(rel[-1], [0, 0, h - 0.02], atol=1e-12)
    soil_faces = np.any(m.faces == len(m.vertices) - 1, axis=1)
    assert np.all(m.face_normals()[soil_faces, 2] > 0)
    # closed as "pot filled up to the soil": between the soil-level cylinder inside and the bounding cylinder
    r_in = min(rb, rt - 0.004) - 0.004
    assert np.pi * r_in**2 * (h - 0.02) < m.signed_volume() < np.pi * rt**2 * h


def test_an_ellipsoid_is_closed_outward_and_holds_its_volume() -> None:
    turn = frame_from_axis(np.array([1.0, 1.0, 0.0]))
    mesh = ellipsoid((0.1, -0.2, 0.3), (0.03, 0.04, 0.08), turn, rings=40, segments=80)
    assert mesh.signed_volume() == pytest.approx(4 / 3 * np.pi * 0.03 * 0.04 * 0.08, rel=0.01)
    edges = np.sort(np.concatenate([mesh.faces[:, [0, 1]], mesh.faces[:, [1, 2]], mesh.faces[:, [2, 0]]]), axis=1)
    assert np.all(np.unique(edges, axis=0, return_counts=True)[1] == 2)  # every edge shared by two faces: watertight
    assert np.allclose(mesh.vertices.mean(axis=0), (0.1, -0.2, 0.3), atol=1e-3)

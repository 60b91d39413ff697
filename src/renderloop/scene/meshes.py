"""Procedural triangle meshes for sweet-pepper plants (pure numpy).

Conventions shared by every builder: metres, world frame z up, faces wound
counter-clockwise seen from outside (outward normals), no degenerate triangles.
Nothing here draws random numbers: the caller passes every random parameter, so
a scene is reproducible from its seed alone and both renderers (Blender, MuJoCo)
see identical geometry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["Mesh", "merge", "frame_from_axis", "tube", "pepper", "leaf", "flower", "pot", "box"]


@dataclass(frozen=True)
class Mesh:
    """Indexed triangle mesh; arrays are normalised to contiguous float64 / int32 on creation."""

    vertices: np.ndarray  # (N, 3) float64
    faces: np.ndarray  # (M, 3) int32
    uv: np.ndarray | None = None  # (N, 2) float64 in [0, 1], per vertex

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        f = np.ascontiguousarray(self.faces, dtype=np.int32).reshape(-1, 3)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        if self.uv is not None:
            uv = np.ascontiguousarray(self.uv, dtype=np.float64).reshape(-1, 2)
            if len(uv) != len(v):
                raise ValueError(f"uv has {len(uv)} rows for {len(v)} vertices")
            object.__setattr__(self, "uv", uv)

    def transformed(self, rotation: np.ndarray, translation: np.ndarray) -> Mesh:
        """Rigid transform v' = R v + t (uv and faces unchanged)."""
        r = np.asarray(rotation, dtype=np.float64).reshape(3, 3)
        t = np.asarray(translation, dtype=np.float64).reshape(3)
        return Mesh(self.vertices @ r.T + t, self.faces, self.uv)

    def face_normals(self) -> np.ndarray:
        """Unnormalised face normals (length = 2 * triangle area)."""
        v = self.vertices[self.faces]
        return np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])

    @property
    def area(self) -> float:
        """Total surface area."""
        return float(0.5 * np.linalg.norm(self.face_normals(), axis=1).sum())

    def signed_volume(self) -> float:
        """Divergence-theorem volume; positive for a closed, outward-oriented mesh."""
        v = self.vertices[self.faces]
        return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0)


def merge(meshes: Sequence[Mesh]) -> Mesh:
    """Concatenate meshes into one; uv is kept only if every part has uv."""
    meshes = list(meshes)
    if not meshes:
        return Mesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    verts = np.concatenate([m.vertices for m in meshes])
    faces = np.concatenate([m.faces.astype(np.int64) + o for m, o in zip(meshes, offsets)])
    uv = np.concatenate([m.uv for m in meshes]) if all(m.uv is not None for m in meshes) else None
    return Mesh(verts, faces, uv)


def _unit(v: ArrayLike, what: str = "vector") -> np.ndarray:
    a = np.asarray(v, dtype=np.float64).reshape(3)
    n = float(np.linalg.norm(a))
    if not np.isfinite(n) or n < 1e-12:
        raise ValueError(f"{what} must be a finite non-zero 3-vector, got {a}")
    return a / n


def frame_from_axis(axis: np.ndarray, twist: float = 0.0) -> np.ndarray:
    """3x3 rotation whose third column is unit(axis).

    The first column is world x projected off the axis (world y when the axis is within
    ~25 degrees of x), so near-vertical stems and peppers share a stable orientation;
    it is then rotated by `twist` (radians) about the axis."""
    z = _unit(axis, "axis")
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = helper - (helper @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c, s = np.cos(twist), np.sin(twist)
    return np.column_stack([c * x + s * y, -s * x + c * y, z])


def _grid_faces(rows: int, cols: int, wrap: bool, offset: int = 0) -> np.ndarray:
    """Two triangles per quad (k,j),(k,j+1),(k+1,j+1),(k+1,j) of a row-major vertex grid.

    With rows advancing along +t and columns counter-clockwise about t, the normal is
    e_col x e_row, i.e. outward for a revolved surface."""
    k, j = np.meshgrid(np.arange(rows - 1), np.arange(cols if wrap else cols - 1), indexing="ij")
    j1 = (j + 1) % cols
    a, b = k * cols + j, k * cols + j1
    c, d = (k + 1) * cols + j1, (k + 1) * cols + j
    return np.stack([a, b, c, a, c, d], axis=-1).reshape(-1, 3) + offset


def _closed_faces(rings: int, segments: int) -> np.ndarray:
    """Faces of the sphere topology [first pole, rings x segments (row-major), last pole].

    Outward when the profile runs from the first to the last pole with the interior on
    its left (counter-clockwise in the (r, z) half-plane) and columns go CCW about +z."""
    j = np.arange(segments)
    j1 = (j + 1) % segments
    last, base = 1 + rings * segments, 1 + (rings - 1) * segments
    top = np.stack([np.zeros_like(j), 1 + j1, 1 + j], axis=-1)
    bottom = np.stack([np.full_like(j, last), base + j, base + j1], axis=-1)
    return np.concatenate([top, _grid_faces(rings, segments, True, offset=1), bottom])


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _transport_normals(points: np.ndarray, tangents: np.ndarray) -> np.ndarray:
    """Rotation-minimising normals by the double-reflection method (Wang et al. 2008).

    Parallel transport instead of Frenet frames: Frenet normals flip at inflections and
    are undefined on straight runs, which twists the tube's quads into slivers."""
    normals = np.empty_like(points)
    normals[0] = frame_from_axis(tangents[0])[:, 0]
    for i in range(len(points) - 1):
        v1 = points[i + 1] - points[i]
        c1 = v1 @ v1
        r_l = normals[i] - (2.0 / c1) * (v1 @ normals[i]) * v1
        t_l = tangents[i] - (2.0 / c1) * (v1 @ tangents[i]) * v1
        v2 = tangents[i + 1] - t_l
        c2 = v2 @ v2
        r = r_l - (2.0 / c2) * (v2 @ r_l) * v2 if c2 > 1e-18 else r_l
        r = r - (r @ tangents[i + 1]) * tangents[i + 1]  # re-orthogonalise against drift
        normals[i + 1] = r / np.linalg.norm(r)
    return normals


def tube(points: np.ndarray, radii: np.ndarray | float, sides: int = 8, caps: bool = True) -> Mesh:
    """Generalised cylinder along a polyline (K>=2 points) with a radius per point.

    Rings are perpendicular to the averaged tangent and carried by parallel transport, so
    the tube does not twist at bends. Consecutive duplicate points are dropped (they would
    give zero-area quads). caps=True closes both ends with flat fans (then watertight);
    vertex layout is [start cap centre, K x sides rings, end cap centre] with caps, else
    just the rings. uv: u around (j/sides), v = normalised arc length."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    r = np.broadcast_to(np.asarray(radii, dtype=np.float64), (len(p),)).copy()
    if sides < 3:
        raise ValueError("sides must be >= 3")
    keep = np.r_[True, np.linalg.norm(np.diff(p, axis=0), axis=1) > 1e-9]
    p, r = p[keep], r[keep]
    if len(p) < 2 or not np.all(np.isfinite(p)):
        raise ValueError("tube needs at least two distinct finite points")
    if not np.all(r > 0):
        raise ValueError("tube radii must be > 0")
    seg = np.diff(p, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    seg /= seg_len[:, None]
    tang = np.empty_like(p)
    tang[0], tang[-1] = seg[0], seg[-1]
    mid = seg[:-1] + seg[1:]
    mid_len = np.linalg.norm(mid, axis=1, keepdims=True)
    tang[1:-1] = np.where(mid_len > 1e-6, mid / np.maximum(mid_len, 1e-12), seg[:-1])
    normals = _transport_normals(p, tang)
    binormals = np.cross(tang, normals)
    theta = 2.0 * np.pi * np.arange(sides) / sides
    offs = np.cos(theta)[None, :, None] * normals[:, None] + np.sin(theta)[None, :, None] * binormals[:, None]
    rings = p[:, None, :] + r[:, None, None] * offs  # (K, sides, 3)
    arc = np.r_[0.0, np.cumsum(seg_len)] / seg_len.sum()
    ring_uv = np.stack(np.broadcast_arrays(np.arange(sides)[None, :] / sides, arc[:, None]), axis=-1)
    k = len(p)
    if not caps:
        return Mesh(rings.reshape(-1, 3), _grid_faces(k, sides, True), ring_uv.reshape(-1, 2))
    verts = np.concatenate([p[:1], rings.reshape(-1, 3), p[-1:]])
    uv = np.concatenate([[[0.5, 0.0]], ring_uv.reshape(-1, 2), [[0.5, 1.0]]])
    return Mesh(verts, _closed_faces(k, sides), uv)


def pepper(center: ArrayLike, axis: ArrayLike, length: float, width: float, lobes: int, lobe_depth: float,
           shoulder: float = 0.25, taper: float = 0.15, twist: float = 0.0,
           rings: int = 16, segments: int = 32) -> Mesh:
    """Blocky lobed sweet (bell) pepper, a closed watertight surface.

    `axis` points from the stalk end (top) to the blossom end (tip); the pepper spans exactly
    `length` along it, centred on `center`. The profile is a superellipse of revolution (rounder
    above the widest ring at `shoulder` of the length, blocky below), tapered by `taper` toward
    the tip, with radius modulated by (1 + lobe_depth * w * cos(lobes * theta)), w growing from
    0.45 at the top to 1 at the tip. The stalk end has a dimple; the blossom end has lobed bumps
    around a slight dip. After shaping, the axial coordinate is rescaled so the extent is exactly
    `length` and the radius so the widest point is exactly width/2 (max diameter = width).
    `twist` rotates the lobes about the axis. Vertex layout: [top pole, rings x segments
    (row-major, ring 0 at the top), bottom pole]. uv: u = theta/(2 pi) (per vertex, so the last
    column of faces wraps u back to 0), v = 0 at the top to 1 at the tip."""
    if length <= 0 or width <= 0:
        raise ValueError("length and width must be > 0")
    if not (0.0 < shoulder < 1.0 and 0.0 <= taper < 1.0 and 0.0 <= lobe_depth < 0.5 and lobes >= 0):
        raise ValueError("need 0<shoulder<1, 0<=taper<1, 0<=lobe_depth<0.5, lobes>=0")
    if rings < 3 or segments < 3:
        raise ValueError("need rings >= 3 and segments >= 3")
    t = np.arange(1, rings + 1) / (rings + 1)
    phi = np.pi * t
    upper = phi < 0.5 * np.pi
    expo = np.where(upper, 0.8, 0.55)  # superellipse n = 2.5 above (rounded shoulder), ~3.6 below (blocky)
    rb = np.sin(phi) ** expo
    c = np.cos(phi)
    a = np.sign(c) * np.abs(c) ** expo  # +1 at the top .. -1 at the tip
    u = np.where(a >= 0, shoulder * (1.0 - a), shoulder - (1.0 - shoulder) * a)  # 0 top .. 1 tip
    theta = 2.0 * np.pi * np.arange(segments) / segments
    lob = np.cos(lobes * theta)[None, :]
    taper_f = 1.0 - taper * np.clip((u - shoulder) / (1.0 - shoulder), 0.0, 1.0)
    lobe_w = 0.45 + 0.55 * u
    radius = (rb * taper_f)[:, None] * (1.0 + lobe_depth * lobe_w[:, None] * lob)
    # Axial shaping in units of length: stalk dimple, blossom-end bumps (under the lobes) and dip.
    dimple, bump, dip = 0.08 * width / length, 0.6 * lobe_depth * width / length, 0.04 * width / length
    top_w = np.where(upper, 1.0 - _smoothstep(rb / 0.45), 0.0)
    bot_w = np.where(upper, 0.0, np.clip((u - 0.6) / 0.4, 0.0, 1.0) ** 2)
    axial = (u + dimple * top_w)[:, None] + bot_w[:, None] * (bump * rb[:, None] * lob - dip * (1.0 - rb[:, None]) ** 2)
    poles = np.array([dimple, 1.0 - dip])
    lo = min(axial.min(), poles.min())
    span = max(axial.max(), poles.max()) - lo
    z = -0.5 * length + length * (axial - lo) / span
    z_poles = -0.5 * length + length * (poles - lo) / span
    radius *= 0.5 * width / radius.max()
    ring_pts = np.stack([radius * np.cos(theta), radius * np.sin(theta), z], axis=-1)
    local = np.concatenate([[[0.0, 0.0, z_poles[0]]], ring_pts.reshape(-1, 3), [[0.0, 0.0, z_poles[1]]]])
    v_coord = (local[:, 2] + 0.5 * length) / length
    u_coord = np.concatenate([[0.5], np.tile(np.arange(segments) / segments, rings), [0.5]])
    rot = frame_from_axis(np.asarray(axis, dtype=np.float64), twist)
    verts = local @ rot.T + np.asarray(center, dtype=np.float64).reshape(3)
    return Mesh(verts, _closed_faces(rings, segments), np.clip(np.stack([u_coord, v_coord], -1), 0.0, 1.0))


def leaf(base: ArrayLike, direction: ArrayLike, up: ArrayLike, length: float, width: float,
         curvature: float, fold: float, twist: float = 0.0, rows: int = 8, cols: int = 4) -> Mesh:
    """Single-sided leaf blade: a grid of `rows` quad rows along the midrib (the last one a fan
    to the pointed tip) and `cols` quads across (rounded up to even so the midrib is a vertex line).

    Ovate outline, widest at ~35% of the length, narrow but non-zero at the base; the widest
    station has half-width exactly width/2. The blade normal is unit(up) made perpendicular to
    unit(direction) and faces are CCW seen from that side. `curvature` (1/m) bends the midrib
    into a circular arc toward -normal, `fold` (rad) lifts both halves toward +normal (V shape),
    `twist` (rad at the tip) rotates the cross-section about the midrib progressively.
    uv: u = 0 at the base to 1 at the tip, v = 0.5 + lateral offset / width (0.5 on the midrib)."""
    if length <= 0 or width <= 0 or rows < 2 or cols < 1:
        raise ValueError("need length>0, width>0, rows>=2, cols>=1")
    d = _unit(direction, "direction")
    n = _unit(np.asarray(up, dtype=np.float64) - (np.asarray(up, dtype=np.float64) @ d) * d, "up (perp. to direction)")
    w = np.cross(n, d)  # (d, w, n) right-handed: d x w = n
    half = (cols + 1) // 2
    s = np.arange(rows) / rows  # stations; the tip (s = 1) is a separate vertex
    g = 0.08 * (1.0 - s) ** 1.3 + s**0.7 * (1.0 - s) ** 1.3
    hw = 0.5 * width * g / g.max()
    ell = np.r_[s, 1.0] * length
    ang = curvature * ell
    safe_k = curvature if abs(curvature) > 1e-12 else 1.0
    along = np.where(abs(curvature) > 1e-12, np.sin(ang) / safe_k, ell)
    drop = np.where(abs(curvature) > 1e-12, (1.0 - np.cos(ang)) / safe_k, 0.0)
    mid = np.asarray(base, dtype=np.float64).reshape(3) + along[:, None] * d - drop[:, None] * n
    nrm = np.sin(ang)[:, None] * d + np.cos(ang)[:, None] * n  # blade normal rotated with the arc
    y = hw[:, None] * (np.arange(2 * half + 1) - half)[None, :] / half  # (rows, 2*half+1)
    lat, up_off = y * np.cos(fold), np.abs(y) * np.sin(fold)
    tau = (twist * s)[:, None]
    lat_t = lat * np.cos(tau) - up_off * np.sin(tau)
    nrm_t = lat * np.sin(tau) + up_off * np.cos(tau)
    grid = mid[:rows, None, :] + lat_t[..., None] * w + nrm_t[..., None] * nrm[:rows, None, :]
    nc = 2 * half + 1
    verts = np.concatenate([grid.reshape(-1, 3), mid[-1:]])
    grid_uv = np.stack(np.broadcast_arrays(s[:, None], 0.5 + y / width), axis=-1).reshape(-1, 2)
    uv = np.clip(np.concatenate([grid_uv, [[1.0, 0.5]]]), 0.0, 1.0)
    j = np.arange(nc - 1)
    last, tip = (rows - 1) * nc, rows * nc
    fan = np.stack([last + j, np.full_like(j, tip), last + j + 1], axis=-1)
    faces = np.concatenate([_grid_faces(rows, nc, False)[:, [0, 2, 1]], fan])  # rows run along d, cols along w
    return Mesh(verts, faces, uv)


def flower(center: ArrayLike, normal: ArrayLike, radius: float, petals: int = 5) -> Mesh:
    """Small star flower: `petals` flat kite-shaped petals (two triangles each) radiating in the
    plane perpendicular to `normal`, plus a centre disc lifted by 4% of the radius (avoids
    z-fighting with the petal roots). Single-sided, facing `normal`; planar uv."""
    if radius <= 0 or petals < 1:
        raise ValueError("need radius > 0 and petals >= 1")
    rot = frame_from_axis(normal)
    e1, e2, nz = rot[:, 0], rot[:, 1], rot[:, 2]
    c = np.asarray(center, dtype=np.float64).reshape(3)
    alpha = 2.0 * np.pi * np.arange(petals) / petals
    ua = np.cos(alpha)[:, None] * e1 + np.sin(alpha)[:, None] * e2
    va = -np.sin(alpha)[:, None] * e1 + np.cos(alpha)[:, None] * e2
    hw = radius * min(0.2, 0.5 * np.sin(np.pi / petals)) if petals > 1 else 0.2 * radius
    p0, midp, tip = c + 0.15 * radius * ua, c + 0.55 * radius * ua, c + radius * ua
    petal_v = np.stack([p0, midp - hw * va, tip, midp + hw * va], axis=1).reshape(-1, 3)
    base = 4 * np.arange(petals)[:, None]
    petal_f = (base + np.array([[0, 1, 2, 0, 2, 3]])).reshape(-1, 3)
    m = max(8, 2 * petals)
    beta = 2.0 * np.pi * np.arange(m) / m
    disc_c = c + 0.04 * radius * nz
    ring = disc_c + 0.22 * radius * (np.cos(beta)[:, None] * e1 + np.sin(beta)[:, None] * e2)
    k = np.arange(m)
    off = 4 * petals
    disc_f = np.stack([np.full_like(k, off), off + 1 + k, off + 1 + (k + 1) % m], axis=-1)
    verts = np.concatenate([petal_v, disc_c[None], ring])
    rel = verts - c
    uv = np.clip(0.5 + 0.5 * np.stack([rel @ e1, rel @ e2], axis=-1) / radius, 0.0, 1.0)
    return Mesh(verts, np.concatenate([petal_f, disc_f]), uv)


def pot(base_center: ArrayLike, radius_bottom: float, radius_top: float, height: float,
        wall: float = 0.004, segments: int = 32) -> Mesh:
    """Plastic plant pot as one closed solid of revolution (watertight, outward normals).

    Profile from the bottom centre: bottom disc, conical outer wall, a ledge out to a vertical
    rim band of radius `radius_top` (the cone ends one wall thickness inside it, so the rim
    reads as a lip), rim top, inner wall one `wall` inside the cone, down to the soil disc at
    height - 0.02. The bottom radius is clamped to radius_top - wall so nothing pokes out.
    uv: u = theta/(2 pi), v = normalised profile arc length."""
    soil = height - 0.02
    rim_h = min(0.012, 0.15 * height)
    lip = wall
    rb = min(radius_bottom, radius_top - lip)
    if not (wall > 0 and soil > 0 and rb > wall and segments >= 3):
        raise ValueError("pot needs wall > 0, height > 0.02, radius_bottom > wall, radius_top > 2*wall")

    def cone(z: float) -> float:
        return rb + (radius_top - lip - rb) * z / height

    if cone(soil) - wall <= 0:
        raise ValueError("pot wall too thick for its radius")
    prof = np.array([
        [rb, 0.0],
        [cone(height - rim_h), height - rim_h],
        [radius_top, height - rim_h],
        [radius_top, height],
        [cone(height) - wall, height],
        [cone(soil) - wall, soil],
    ])
    theta = 2.0 * np.pi * np.arange(segments) / segments
    rings = np.stack(np.broadcast_arrays(prof[:, :1] * np.cos(theta), prof[:, :1] * np.sin(theta),
                                         prof[:, 1:2]), axis=-1)
    full = np.concatenate([[[0.0, 0.0]], prof, [[0.0, soil]]])
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(full, axis=0), axis=1))]
    arc /= arc[-1]
    ring_uv = np.stack(np.broadcast_arrays(np.arange(segments)[None, :] / segments, arc[1:-1, None]), axis=-1)
    c = np.asarray(base_center, dtype=np.float64).reshape(3)
    verts = np.concatenate([[[0.0, 0.0, 0.0]], rings.reshape(-1, 3), [[0.0, 0.0, soil]]]) + c
    uv = np.concatenate([[[0.5, 0.0]], ring_uv.reshape(-1, 2), [[0.5, 1.0]]])
    return Mesh(verts, _closed_faces(len(prof), segments), uv)


def box(center: ArrayLike, size: ArrayLike) -> Mesh:
    """Axis-aligned closed box (8 vertices, 12 triangles, outward normals); size = full edge lengths."""
    sz = np.broadcast_to(np.asarray(size, dtype=np.float64), (3,))
    if not np.all(sz > 0):
        raise ValueError("box size must be > 0")
    bits = (np.arange(8)[:, None] >> np.arange(3)) & 1  # vertex i has corner bits (x, y, z)
    verts = np.asarray(center, dtype=np.float64).reshape(3) + (bits - 0.5) * sz
    faces = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                      [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
    return Mesh(verts, faces)

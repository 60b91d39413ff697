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

__all__ = ["Mesh", "merge", "frame_from_axis", "tube", "pepper", "leaf", "LeafShape", "pepper_leaf", "calyx", "flower",
           "pot", "box", "ellipsoid"]


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
        """Transform v' = R v + t (uv and faces unchanged): rigid for a rotation R; a rotation times a
        positive diagonal scale keeps the winding, so the normals stay outward."""
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


@dataclass(frozen=True)
class LeafShape:
    """The shape of a sweet-pepper leaf template (`pepper_leaf`): angles in radians, amplitudes as fractions
    of the blade's length; `hole` and `bite` (None: a whole leaf) are damage, in blade coordinates
    (t along the midrib 0..1, y across over the half-width -1..1)."""

    droop: float  # the midrib's bend over the blade, tip down
    rise: float  # the petiole's angle above the blade's base plane
    fold: float  # both halves lifted about the midrib (a V)
    curl: float  # the margins rolled down, at the margin
    twist: float  # the cross-section turned about the midrib at the tip
    wrinkle: float  # puckering between the lateral veins
    wave: float  # undulation of the margin
    phase: float  # where along the blade the puckers and waves sit, 0..1
    hole: tuple[float, float, float] | None = None  # (t, y, radius in t units): an eaten hole
    bite: tuple[float, float, float] | None = None  # (t from, t to, depth over the half-width) on the +y margin


PEPPER_LEAF_WIDTH = 0.48  # blade width over length of every template; a leaf's own ratio scales it across


def pepper_leaf(shape: LeafShape, petiole: float = 0.25, stations: int = 18, half: int = 4) -> Mesh:
    """Sweet-pepper leaf template: blade length 1 along local +x (beyond a petiole of length `petiole` that
    starts at the origin), width PEPPER_LEAF_WIDTH across +y, its upper side facing +z, single-sided, faces
    CCW seen from the upper side. Scaled (length, width / PEPPER_LEAF_WIDTH, length) and placed, it becomes
    every leaf of the style, so a plant's hundred leaves share a few meshes (instances in Cycles).

    Ovate-lanceolate outline (widest at 0.38 of the blade, a cuneate base running into the petiole,
    acuminate tip), the midrib a vertex line; the midrib bends down by `droop` toward the tip, the halves
    fold up and the margins curl down, the blade puckers between seven pairs of lateral veins and its
    margin waves. uv: u = 0 at the blade's base to 1 at the tip (0 on the petiole), v = 0.5 + y / width
    (0.5 on the midrib), as `leaf` has them, so one vein texture serves both."""
    if stations < 4 or half < 1 or petiole < 0:
        raise ValueError("need stations >= 4, half >= 1, petiole >= 0")
    petiole_stations = 3 if petiole > 0 else 0
    ell = np.r_[np.linspace(0.0, petiole, petiole_stations, endpoint=False), petiole + np.arange(stations) / stations]
    t = np.clip(ell - petiole, 0.0, 1.0)  # blade fraction; 0 on the petiole
    g = t * (1.0 - t) ** 1.6  # widest at 0.38 of the blade
    stalk = 0.035  # the petiole's half-width over the blade's width
    hw = PEPPER_LEAF_WIDTH * np.maximum(0.5 * g / g.max(), stalk)
    angle = np.where(ell <= petiole, shape.rise, shape.rise * (1.0 - _smoothstep(t / 0.3)) - shape.droop * t**1.5)
    ell_all = np.r_[ell, petiole + 1.0]
    angle_all = np.r_[angle, -shape.droop]
    steps = np.diff(ell_all)
    mid_angle = 0.5 * (angle_all[1:] + angle_all[:-1])
    mid = np.zeros((len(ell_all), 3))
    mid[1:, 0] = np.cumsum(steps * np.cos(mid_angle))
    mid[1:, 2] = np.cumsum(steps * np.sin(mid_angle))
    normal = np.stack([-np.sin(angle_all), np.zeros_like(angle_all), np.cos(angle_all)], axis=-1)
    across = (np.arange(2 * half + 1) - half) / half  # -1..1 over the half-width
    y = hw[:, None] * across[None, :]
    a = np.abs(across)[None, :]
    blade = (t > 0)[:, None]
    tt = t[:, None]
    lift = np.where(blade, np.abs(y) * np.tan(shape.fold) - shape.curl * a**2, 0.0)
    pucker = shape.wrinkle * np.sin(np.pi * a) * np.sin(2 * np.pi * (7.0 * tt + 1.6 * a + shape.phase))
    ripple = shape.wave * a**3 * np.sin(2 * np.pi * (4.0 * tt + shape.phase) + 2.0 * np.sign(across)[None, :])
    lift = lift + np.where(blade, (pucker + ripple) * np.sin(np.pi * tt) ** 0.5, 0.0)
    tau = shape.twist * tt
    lat = y * np.cos(tau) - lift * np.sin(tau)
    up = y * np.sin(tau) + lift * np.cos(tau)
    rows = len(ell)
    grid = mid[:rows, None, :] + lat[..., None] * np.array([0.0, 1.0, 0.0]) + up[..., None] * normal[:rows, None, :]
    nc = 2 * half + 1
    verts = np.concatenate([grid.reshape(-1, 3), mid[-1:]])
    grid_uv = np.stack(np.broadcast_arrays(t[:, None], 0.5 + y / PEPPER_LEAF_WIDTH), axis=-1).reshape(-1, 2)
    uv = np.clip(np.concatenate([grid_uv, [[1.0, 0.5]]]), 0.0, 1.0)
    j = np.arange(nc - 1)
    last, tip = (rows - 1) * nc, rows * nc
    fan = np.stack([last + j, np.full_like(j, tip), last + j + 1], axis=-1)
    faces = np.concatenate([_grid_faces(rows, nc, False)[:, [0, 2, 1]], fan])
    keep = np.ones(len(faces), dtype=bool)
    if shape.hole is not None or shape.bite is not None:
        station = np.r_[t, 1.0][faces // nc].mean(axis=1)  # the tip vertex is row `rows`
        side = np.r_[np.broadcast_to(across, (rows, nc)).ravel(), 0.0][faces].mean(axis=1)
        if shape.hole is not None:
            ht, hy, hr = shape.hole
            keep &= np.hypot((station - ht) / hr, (side - hy) * 0.5 * PEPPER_LEAF_WIDTH / hr) > 1.0
        if shape.bite is not None:
            lo, hi, depth = shape.bite
            inside = (station > lo) & (station < hi)
            arc = np.sin(np.pi * np.clip((station - lo) / (hi - lo), 0.0, 1.0))
            keep &= ~(inside & (side > 1.0 - depth * arc))
    return Mesh(verts, faces[keep], uv)


def calyx(center: ArrayLike, axis: ArrayLike, length: float, width: float, lobes: int, lobe_depth: float,
          twist: float, sepals: int, reach: float, bound: float, lift: float = 0.0015, rings: int = 4) -> Mesh:
    """The calyx of the `pepper` of these parameters: a star of `sepals` pointed sepals reaching `reach` from
    the axis, lying `lift` above the fruit's skin around its stalk end (single-sided, facing away from the
    fruit). Vertices farther than `bound` from `center` (the fruit's bounding radius) are pulled in to it,
    so the calyx stays inside the fruit's bounding sphere."""
    if sepals < 3 or reach <= 0 or rings < 1:
        raise ValueError("need sepals >= 3, reach > 0, rings >= 1")
    segments = 32
    local = pepper(np.zeros(3), (0.0, 0.0, 1.0), length, width, lobes, lobe_depth, twist=0.0, segments=segments).vertices
    ring_count = (len(local) - 2) // segments
    columns = local[1:-1].reshape(ring_count, segments, 3)[: ring_count // 2]  # the upper half, top ring first
    radial = np.hypot(columns[..., 0], columns[..., 1])
    spokes = 4 * sepals
    phi = 2.0 * np.pi * np.arange(spokes) / spokes
    tooth = np.abs(np.cos(0.5 * sepals * phi)) ** 4  # 1 at a sepal's tip, 0 between two
    outline = reach * (0.45 + 0.55 * tooth)
    nearest = np.rint(phi / (2.0 * np.pi) * segments).astype(int) % segments
    fraction = np.arange(1, rings + 1) / rings
    r = outline[None, :] * fraction[:, None]  # (rings, spokes)
    z = np.empty_like(r)
    for k in range(spokes):
        profile_r = np.r_[0.0, radial[:, nearest[k]]]
        profile_z = np.r_[local[0, 2], columns[:, nearest[k], 2]]
        widest = int(np.argmax(profile_r))
        z[:, k] = np.interp(r[:, k], profile_r[: widest + 1], profile_z[: widest + 1])
    pts = np.stack([r * np.cos(phi), r * np.sin(phi), z - lift], axis=-1).reshape(-1, 3)
    verts_local = np.concatenate([[[0.0, 0.0, local[0, 2] - lift]], pts])
    rot = frame_from_axis(np.asarray(axis, dtype=np.float64), twist)
    c = np.asarray(center, dtype=np.float64).reshape(3)
    verts = verts_local @ rot.T
    distance = np.linalg.norm(verts, axis=1)
    verts *= np.minimum(1.0, bound / np.maximum(distance, 1e-12))[:, None]
    k = np.arange(spokes)
    k1 = (k + 1) % spokes
    centre_fan = np.stack([np.zeros_like(k), 1 + k1, 1 + k], axis=-1)  # seen from -z (away from the fruit)
    faces = [centre_fan]
    for ring in range(rings - 1):
        a, b = 1 + ring * spokes, 1 + (ring + 1) * spokes
        faces.append(np.stack([a + k, a + k1, b + k1], axis=-1))
        faces.append(np.stack([a + k, b + k1, b + k], axis=-1))
    uv = np.clip(0.5 + 0.5 * verts_local[:, :2] / reach, 0.0, 1.0)
    return Mesh(verts + c, np.concatenate(faces), uv)


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


def ellipsoid(center: ArrayLike, radii: ArrayLike, rotation: ArrayLike | None = None, rings: int = 12,
              segments: int = 24) -> Mesh:
    """Closed ellipsoid with semi-axes `radii` along the columns of `rotation` (identity: x, y, z), centred on
    `center`: an apple, a tomato, a lemon, a stone."""
    if rings < 2 or segments < 3:
        raise ValueError(f"ellipsoid needs at least 2 rings and 3 segments, got {rings} and {segments}")
    polar = np.linspace(np.pi, 0.0, rings + 2)[1:-1]  # bottom pole to top pole: the interior on the profile's left
    azimuth = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([np.outer(np.sin(polar), np.cos(azimuth)), np.outer(np.sin(polar), np.sin(azimuth)),
                     np.repeat(np.cos(polar)[:, None], segments, axis=1)], axis=-1).reshape(-1, 3)
    unit = np.concatenate([[[0.0, 0.0, -1.0]], ring, [[0.0, 0.0, 1.0]]])
    r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64).reshape(3, 3)
    return Mesh((unit * np.asarray(radii, dtype=np.float64)) @ r.T + np.asarray(center, dtype=np.float64),
                _closed_faces(rings, segments))

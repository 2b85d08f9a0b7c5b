"""Named scenes as triangle meshes for open3d's RaycastingScene: terrain plus structure.

The terrain is a smooth heightfield h(x, y) (gentle relief + fine roughness) shared with the
body-pose model, so the robot's pitch and roll follow the ground the LiDAR sees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from mrnc_eval.errors import UnknownName

SCENES = ("yard", "forest", "corridor", "field", "open_field")


@dataclass(frozen=True)
class Terrain:
    """h(x, y) = gentle relief (wavelengths 50-125 m) + fine roughness (wavelengths 2.7-3.7 m), m.
    Analytic, so the body pose and its derivatives are smooth and exact."""

    amplitude_m: float
    roughness_m: float
    seed: int
    _k: np.ndarray = field(init=False, repr=False, compare=False)
    _ph: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        rng = np.random.default_rng(self.seed)
        object.__setattr__(self, "_k", rng.uniform(0.05, 0.12, 4))
        object.__setattr__(self, "_ph", rng.uniform(0, 2 * np.pi, 4))

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        k, ph, a = self._k, self._ph, self.amplitude_m * 0.5
        return (a * (np.sin(k[0] * x + ph[0]) * np.cos(k[1] * y + ph[1]) + 0.5 * np.sin(k[2] * (x + y) + ph[2]))
                + self.roughness_m * np.sin(1.7 * x + ph[3]) * np.sin(2.3 * y))

    def gradient(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact slope (dh/dx, dh/dy), m/m."""
        k, ph, a, r = self._k, self._ph, self.amplitude_m * 0.5, self.roughness_m
        diag = 0.5 * k[2] * np.cos(k[2] * (x + y) + ph[2])
        gx = a * (k[0] * np.cos(k[0] * x + ph[0]) * np.cos(k[1] * y + ph[1]) + diag) \
            + r * 1.7 * np.cos(1.7 * x + ph[3]) * np.sin(2.3 * y)
        gy = a * (-k[1] * np.sin(k[0] * x + ph[0]) * np.sin(k[1] * y + ph[1]) + diag) \
            + r * 2.3 * np.sin(1.7 * x + ph[3]) * np.cos(2.3 * y)
        return gx, gy


@dataclass
class Scene:
    name: str
    terrain: Terrain
    vertices: list[np.ndarray] = field(default_factory=list)
    triangles: list[np.ndarray] = field(default_factory=list)
    reflectivity: list[float] = field(default_factory=list)  # per mesh, 0..1

    def add(self, vertices: np.ndarray, triangles: np.ndarray, reflectivity: float) -> None:
        self.vertices.append(np.asarray(vertices, np.float32))
        self.triangles.append(np.asarray(triangles, np.uint32))
        self.reflectivity.append(reflectivity)

    def raycasting_scene(self):
        import open3d as o3d

        rs = o3d.t.geometry.RaycastingScene()
        for v, t in zip(self.vertices, self.triangles, strict=True):
            rs.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(t))
        return rs


Mesh = tuple[np.ndarray, np.ndarray]  # (vertices (V, 3) m, triangles (T, 3) vertex indices)


def box_mesh(cx, cy, z0, sx, sy, sz, yaw=0.0) -> Mesh:
    c, s = math.cos(yaw), math.sin(yaw)
    corners = np.array([[dx, dy, dz] for dz in (0, sz) for dy in (-sy / 2, sy / 2) for dx in (-sx / 2, sx / 2)])
    xy = corners[:, :2] @ np.array([[c, s], [-s, c]])
    v = np.c_[xy[:, 0] + cx, xy[:, 1] + cy, corners[:, 2] + z0]
    t = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
    return v, t


def _cylinder(cx, cy, z0, radius, height, n=12) -> Mesh:
    a = 2 * np.pi * np.arange(n) / n
    ring = np.c_[cx + radius * np.cos(a), cy + radius * np.sin(a)]
    v = np.r_[np.c_[ring, np.full(n, z0)], np.c_[ring, np.full(n, z0 + height)]]
    t = []
    for k in range(n):
        j = (k + 1) % n
        t += [[k, j, n + k], [j, n + j, n + k]]
    return v, np.asarray(t)


def _sphere(cx, cy, cz, r, n=8) -> Mesh:
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_sphere(radius=r, resolution=n)
    return np.asarray(m.vertices) + [cx, cy, cz], np.asarray(m.triangles)


def _ground(terrain: Terrain, half: float, step: float) -> Mesh:
    g = np.arange(-half, half + step, step)
    X, Y = np.meshgrid(g, g)
    Z = terrain.height(X, Y)
    n = g.size
    v = np.c_[X.ravel(), Y.ravel(), Z.ravel()]
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    t = np.r_[np.c_[a, c, b], np.c_[b, c, d]]
    return v, t


# NIR (865 nm) albedo of each material, 0..1; drives calibrated reflectivity and signal
MATERIALS = {"soil": 0.25, "concrete": 0.4, "container": 0.55, "metal_pole": 0.6, "vehicle": 0.45,
             "bark": 0.3, "foliage": 0.5, "rock": 0.35}


def build_scene(name: str, *, seed: int = 0, amplitude_m: float = 0.3, roughness_m: float = 0.02,
                centre=(0.0, 0.0), half_size_m: float = 40.0, keep_clear_xy: np.ndarray | None = None,
                clearance_m: float = 1.5, scale: float = 1.0) -> Scene:
    """A named scene around `centre` (m): yard (buildings, containers, poles, vehicles), forest
    (a forest edge: dense trees on one side, open ground with shrubs and rocks on the other),
    corridor (two long featureless walls: degenerate along its axis), field (open ground only:
    degenerate) or open_field (open ground with a few lone structures: most of the time only 1-3
    within 30 m). The layout is a pure function of `seed` and `keep_clear_xy`: no object (its
    whole footprint, tree crowns included) comes within `clearance_m` of those points (m, the
    driven path), so the machine never drives through a trunk or with its LiDAR inside a crown.
    `scale` stretches the layout for larger paths: distances x scale, object counts x scale^2
    (the same density over a larger area)."""
    if name not in SCENES:
        raise UnknownName("scene", name, SCENES)
    terrain = Terrain(0.0 if name == "corridor" else amplitude_m, roughness_m, seed)
    scene = Scene(name, terrain)
    cx0, cy0 = centre
    scene.add(*_ground(terrain, half_size_m * scale + max(abs(cx0), abs(cy0)), 0.5), MATERIALS["soil"])
    placer = _Placer(np.random.default_rng(seed + 1000), centre, scale, keep_clear_xy, clearance_m)
    furnish = {"yard": _furnish_yard, "forest": _furnish_forest, "corridor": _furnish_corridor,
               "open_field": _furnish_open_field}.get(name)
    if furnish is not None:  # "field": open ground only (degenerate: no structure)
        furnish(scene, placer)
    return scene


class _Placer:
    """Draws object positions around the scene centre, clear of the driven path. All of a scene's
    random numbers come from its one generator, in a fixed order, so a layout is a pure function of
    the seed."""

    def __init__(self, rng: np.random.Generator, centre: tuple[float, float], scale: float,
                 keep_clear_xy: np.ndarray | None, clearance_m: float) -> None:
        self.rng, self.centre, self.scale, self.clearance_m = rng, centre, scale, clearance_m
        self.clear = None
        if keep_clear_xy is not None and len(keep_clear_xy):
            from scipy.spatial import cKDTree

            self.clear = cKDTree(np.asarray(keep_clear_xy, float)[:, :2])

    def place(self, n, r_min, r_max, sector=(0.0, 2 * np.pi), footprint_m=0.0) -> list[tuple[float, float]]:
        """n positions in the annulus sector; redrawn (at most 100 times) while the footprint
        (radius, m) would reach within clearance_m of the path."""
        cx0, cy0 = self.centre
        out = []
        for _ in range(round(n * self.scale ** 2)):
            for _attempt in range(100):
                r, a = self.rng.uniform(r_min * self.scale, r_max * self.scale), self.rng.uniform(*sector)
                xy = (cx0 + r * math.cos(a), cy0 + r * math.sin(a))
                if self.clear is None or self.clear.query(xy)[0] >= self.clearance_m + footprint_m:
                    out.append(xy)
                    break
        return out


def _ground_z(scene: Scene, x: float, y: float) -> float:
    return float(scene.terrain.height(np.array(x), np.array(y)))


def _tree(scene: Scene, x: float, y: float, trunk_r: float, height: float, crown_r: float) -> None:
    scene.add(*_cylinder(x, y, _ground_z(scene, x, y) - 0.2, trunk_r, height), MATERIALS["bark"])
    scene.add(*_sphere(x, y, _ground_z(scene, x, y) + height, crown_r), MATERIALS["foliage"])


def _furnish_yard(scene: Scene, placer: _Placer) -> None:
    rng, z = placer.rng, partial(_ground_z, scene)
    for x, y in placer.place(6, 12, 30, footprint_m=8.5):  # buildings / walls (15 x 8 m at most)
        scene.add(*box_mesh(x, y, z(x, y) - 0.5, rng.uniform(6, 15), rng.uniform(3, 8), rng.uniform(3, 8),
                            rng.uniform(0, np.pi)), MATERIALS["concrete"])
    for x, y in placer.place(8, 9, 25, footprint_m=3.3):  # 20 ft containers
        scene.add(*box_mesh(x, y, z(x, y) - 0.2, 6.1, 2.4, 2.6, rng.uniform(0, np.pi)), MATERIALS["container"])
    for x, y in placer.place(10, 9, 28, footprint_m=0.12):  # lamp poles
        scene.add(*_cylinder(x, y, z(x, y) - 0.2, 0.12, 6.0), MATERIALS["metal_pole"])
    for x, y in placer.place(3, 10, 20, footprint_m=2.5):  # parked vehicles
        scene.add(*box_mesh(x, y, z(x, y), 4.5, 1.9, 1.6, rng.uniform(0, np.pi)), MATERIALS["vehicle"])


def _furnish_forest(scene: Scene, placer: _Placer) -> None:
    """A forest edge: trees in a 200 deg sector; the rest is open ground with lone trees and rocks."""
    rng, z = placer.rng, partial(_ground_z, scene)
    for x, y in placer.place(70, 8, 38, (0.0, np.radians(200)), footprint_m=3.0):  # crown radius
        _tree(scene, x, y, rng.uniform(0.12, 0.35), rng.uniform(5, 12), rng.uniform(1.5, 3.0))
    for x, y in placer.place(5, 10, 30, (np.radians(200), 2 * np.pi), footprint_m=2.5):  # lone trees in the open
        _tree(scene, x, y, rng.uniform(0.15, 0.3), rng.uniform(4, 8), rng.uniform(1.5, 2.5))
    for x, y in placer.place(8, 9, 30, (np.radians(200), 2 * np.pi), footprint_m=1.2):  # rocks and stumps
        size = rng.uniform(0.8, 2.0), rng.uniform(0.6, 1.2), rng.uniform(0.6, 1.2)
        scene.add(*box_mesh(x, y, z(x, y) - 0.3, *size, rng.uniform(0, np.pi)), MATERIALS["rock"])


def _furnish_corridor(scene: Scene, placer: _Placer) -> None:
    """Two long featureless walls 8 m apart, along x."""
    cx0, cy0 = placer.centre
    for side in (-1, 1):
        scene.add(*box_mesh(cx0, cy0 + side * 4.0, -0.5, 400.0, 0.3, 4.0), MATERIALS["concrete"])


def _furnish_open_field(scene: Scene, placer: _Placer) -> None:
    """Open ground where a machine works: six lone structures 10-55 m from the centre (about one per
    1500 m^2, so 1-3 within 30 m of the path most of the time): two trees, two utility poles, a
    parked machine and a 20 ft container."""
    rng, z = placer.rng, partial(_ground_z, scene)
    for x, y in placer.place(2, 10, 55, footprint_m=3.0):  # lone trees (crown radius)
        _tree(scene, x, y, rng.uniform(0.15, 0.35), rng.uniform(5, 10), rng.uniform(1.5, 3.0))
    for x, y in placer.place(2, 10, 55, footprint_m=0.15):  # utility poles
        scene.add(*_cylinder(x, y, z(x, y) - 0.2, 0.15, 8.0), MATERIALS["metal_pole"])
    for x, y in placer.place(1, 10, 55, footprint_m=2.7):  # a parked machine
        scene.add(*box_mesh(x, y, z(x, y), 4.5, 2.2, 2.8, rng.uniform(0, np.pi)), MATERIALS["vehicle"])
    for x, y in placer.place(1, 10, 55, footprint_m=3.3):  # a 20 ft container
        scene.add(*box_mesh(x, y, z(x, y) - 0.2, 6.1, 2.4, 2.6, rng.uniform(0, np.pi)), MATERIALS["container"])

"""A Newton scene: one garment (VBD or Style3D cloth) against an animated body-mesh collider.

Importing this module sets warp up through :mod:`drapebench.warp_env` (kernels compiled once per machine,
about 50 s the first time on CPU).
"""

from __future__ import annotations

import numpy as np

from drapebench.extras import require
from drapebench.physics.material import Material
from drapebench.reference.materials import panel_coordinates, style3d_parameters, vbd_edge_stiffness, vbd_parameters
from drapebench.reference.settings import SimSettings
from drapebench.warp_env import wp

newton = require("newton", "the reference simulator (reference=vbd|style3d, the simulator run as a method, data presets)")


@wp.kernel
def _set_pinned(
    index: wp.array(dtype=wp.int32),
    target_q: wp.array(dtype=wp.vec3),
    target_qd: wp.array(dtype=wp.vec3),
    q: wp.array(dtype=wp.vec3),
    qd: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    q[index[i]] = target_q[i]
    qd[index[i]] = target_qd[i]


def resolve_device(device: str | None) -> str:
    """``device`` as a warp device name; None picks ``cuda:0`` when available, else ``cpu``."""
    if device is None:
        return "cuda:0" if wp.is_cuda_available() else "cpu"
    if device.startswith("cuda") and not wp.is_cuda_available():
        raise ValueError(f"reference device {device!r} requested but warp finds no CUDA device; use device='cpu'")
    return str(wp.get_device(device))


class ClothScene:
    """Garment particles + a body mesh shape whose points and velocities are rewritten every substep.

    rest (V, 3) template (rest shape), faces (F, 3), start (V, 3) initial positions, body_points
    (Vb, 3) and body_faces (Fb, 3) the collider at its first pose, pins (P,) kinematic vertex
    indices (driven by :meth:`set_pinned`), all numpy, metres.
    """

    def __init__(self, rest, faces, start, body_points, body_faces, pins, material: Material, settings: SimSettings,
                 device: str) -> None:  # fmt: skip
        self.settings = settings
        self.device = device
        self.n_vertices = len(rest)
        faces = np.asarray(faces, dtype=np.int64)
        builder = newton.ModelBuilder(up_axis=newton.Axis.Z)
        common = dict(pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), vel=wp.vec3(0.0, 0.0, 0.0), scale=1.0,
                      vertices=np.asarray(rest, dtype=np.float64).tolist(), indices=faces.ravel().tolist())  # fmt: skip
        if settings.solver == "vbd":
            p = vbd_parameters(material, settings.damping)
            builder.add_cloth_mesh(**common, **p, edge_ke=0.0, edge_kd=0.0)
            ke = vbd_edge_stiffness(rest, np.asarray(builder.edge_indices), material.bending)
            builder.edge_bending_properties = [(float(k), float(settings.damping * k)) for k in ke]
            builder.color()
        else:
            from newton.solvers import style3d

            newton.solvers.SolverStyle3D.register_custom_attributes(builder)
            p = style3d_parameters(material)
            builder.default_edge_ke, builder.default_edge_kd = p["bend_ke"], 0.0
            panel, panel_faces = panel_coordinates(rest, faces)
            style3d.add_cloth_mesh(builder, **common, density=p["density"], particle_radius=p["particle_radius"],
                                   tri_aniso_ke=wp.vec3(*p["tri_aniso_ke"]), panel_verts=panel.tolist(),
                                   panel_indices=panel_faces.ravel().tolist())  # fmt: skip
        if builder.particle_count != self.n_vertices or len(builder.tri_indices) != len(faces):
            raise ValueError(f"newton dropped degenerate garment triangles ({len(builder.tri_indices)} of {len(faces)} kept)")
        shape_cfg = newton.ModelBuilder.ShapeConfig(ke=settings.contact_ke, kd=settings.contact_kd, mu=material.friction,
                                                    margin=0.0, gap=settings.contact_gap, has_shape_collision=False)  # fmt: skip
        body_mesh = newton.Mesh(np.asarray(body_points, dtype=np.float32), np.asarray(body_faces, dtype=np.int32).ravel(),
                                compute_inertia=False)  # fmt: skip
        self.shape = builder.add_shape_mesh(body=-1, mesh=body_mesh, cfg=shape_cfg)
        self.model = model = builder.finalize(device=device)
        self.body_mesh = body_mesh.mesh
        model.set_gravity(tuple(material.gravity))
        model.soft_contact_ke = settings.contact_ke
        model.soft_contact_kd = settings.contact_kd
        model.soft_contact_mu = material.friction

        pins = np.asarray(pins, dtype=np.int32)
        self.pins = wp.array(pins, dtype=wp.int32, device=device)
        if len(pins):
            mass = model.particle_mass.numpy()
            inv_mass = model.particle_inv_mass.numpy()
            mass[pins] = 0.0
            inv_mass[pins] = 0.0
            model.particle_mass.assign(mass)
            model.particle_inv_mass.assign(inv_mass)

        self.state_0, self.state_1 = model.state(), model.state()
        self.state_0.particle_q.assign(np.asarray(start, dtype=np.float32))
        self.control = model.control()
        self.pipeline = newton.CollisionPipeline(model, soft_contact_gap=settings.contact_gap)
        self.contacts = self.pipeline.contacts()
        eps = material.collision_thickness
        if settings.solver == "vbd":
            extra = dict(particle_self_contact_margin=eps, particle_self_contact_gap=eps) if settings.self_contact else {}
            self.solver = newton.solvers.SolverVBD(model, iterations=int(settings.iterations),
                                                   particle_enable_self_contact=bool(settings.self_contact), **extra)  # fmt: skip
        else:
            self.solver = newton.solvers.SolverStyle3D(model, config=newton.solvers.SolverStyle3D.Config(
                iterations=int(settings.iterations)))  # fmt: skip
            self.solver.collision.radius = 0.5 * eps  # self-contact thickness 2 x radius = eps
            if not settings.self_contact:
                c = self.solver.collision
                c.stiff_vf = c.stiff_ee = c.stiff_ef = 0.0
        self._aabb_lo = np.zeros((model.shape_count, 3), dtype=np.float32)
        self._aabb_hi = np.zeros((model.shape_count, 3), dtype=np.float32)

    def set_body(self, points: np.ndarray, velocities: np.ndarray) -> None:
        """Move the collider: (Vb, 3) points (m) and their velocities (m/s); refits its BVH and AABB."""
        self.body_mesh.points.assign(points)
        self.body_mesh.velocities.assign(velocities)
        self.body_mesh.refit()
        lo = self.model.shape_collision_aabb_lower.numpy()
        hi = self.model.shape_collision_aabb_upper.numpy()
        lo[self.shape], hi[self.shape] = points.min(0), points.max(0)
        self.model.shape_collision_aabb_lower.assign(lo)
        self.model.shape_collision_aabb_upper.assign(hi)

    def set_pinned(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Place the pinned vertices at (P, 3) positions with (P, 3) velocities."""
        if self.pins.shape[0]:
            wp.launch(_set_pinned, dim=self.pins.shape[0], device=self.device,
                      inputs=[self.pins, wp.array(q, dtype=wp.vec3, device=self.device),
                              wp.array(qd, dtype=wp.vec3, device=self.device)],
                      outputs=[self.state_0.particle_q, self.state_0.particle_qd])  # fmt: skip

    def begin_frame(self) -> None:
        """Per-frame upkeep (Style3D rebuilds its self-collision BVH)."""
        if self.settings.solver == "style3d":
            self.solver.rebuild_bvh(self.state_0)

    def step(self, dt: float) -> None:
        """One solver step of ``dt`` seconds against the collider as last set."""
        self.state_0.clear_forces()
        self.pipeline.collide(self.state_0, self.contacts)
        self.solver.step(self.state_0, self.state_1, self.control, self.contacts, dt)
        self.state_0, self.state_1 = self.state_1, self.state_0

    def positions(self) -> np.ndarray:
        """(V, 3) float32 copy of the garment's current positions."""
        return self.state_0.particle_q.numpy().copy()

    def velocities(self) -> np.ndarray:
        """(V, 3) float32 copy of the garment's current velocities."""
        return self.state_0.particle_qd.numpy().copy()

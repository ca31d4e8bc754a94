"""What a `collide.rerun_log.RerunLog` draws: the blueprint, the static geoms and styles, and per
step the geoms' poses, the bounds and the pair lines (`_Scene`, a part of `RerunLog`).
"""

from __future__ import annotations

import numpy as np

from ..contacts import never_collides
from ._convert import (_CANDIDATE, _KINDS, _MISSED, _MUJOCO, _OURS, _SPHERE, _T, _quat_xyzw, _rgba8,
                       _vertex_normals)


class _Scene:
    """The drawing half of `RerunLog`: what is logged once per model, and the geometry of a step.

    It reads the log's ``rr``, ``rec``, ``model``, ``ngeom``, ``visual``, ``contacts``,
    ``merge_meshes``, ``_deferred`` and ``_poses``; `_static` sets the rest it uses.
    """

    # ------------------------------------------------------------------ set-up, once per model

    def _blueprint(self):
        rrb = self.rr.blueprint
        return rrb.Blueprint(
            rrb.Horizontal(
                rrb.Spatial3DView(origin="/world", name="scene"),
                rrb.Vertical(
                    rrb.TimeSeriesView(origin="/stats/pairs", name="geom pairs per step"),
                    rrb.TimeSeriesView(origin="/stats/contacts", name="contact points per step"),
                    rrb.TimeSeriesView(origin="/stats/time_us", name="time per step (us)"),
                ),
                column_shares=[3, 2],
            ),
        )

    def _static(self) -> None:
        rr, m, rec = self.rr, self.model, self.rec
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)  # MuJoCo's z is up
        gtype = np.asarray(m.geom_type)
        self.geom_collides = collides = ~never_collides(m, self.ngeom)
        rgba = np.array(m.geom_rgba, dtype=np.float64)
        matid = np.asarray(m.geom_matid)
        has_mat = matid >= 0
        rgba[has_mat] = np.asarray(m.mat_rgba)[matid[has_mat]]
        self._rgba = _rgba8(rgba)
        size = np.asarray(m.geom_size, dtype=np.float64)
        extent = float(m.stat.extent) if float(m.stat.extent) > 0 else 1.0
        self.normal_length = 0.05 * extent
        self._size, self._extent = size, extent
        self._groups = []  # (entity, kind, geom ids, static half sizes or (lengths, radii))
        self._meshes = []  # (entity, geom id): a mesh geom of its own, moved by a Transform3D
        self._merged = []  # (entity, vertex geom ids, local vertices, local normals): meshes merged
        for prefix, mask in (("world/geoms", collides), ("world/visual", ~collides if self.visual else None)):
            if mask is None:
                continue
            for t, kind in _KINDS.items():
                ids = np.flatnonzero(mask & (gtype == t))
                if len(ids):
                    self._groups.append((f"{prefix}/{kind}", t, ids))
                    self._static_group(f"{prefix}/{kind}", t, ids)
            mesh_geoms = np.flatnonzero(mask & (gtype == _T["mesh"]))
            parts = []  # (geom, vertices in the geom frame, faces, vertex normals)
            for g in mesh_geoms:
                mesh = int(m.geom_dataid[g])
                v0, nv = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
                f0, nf = int(m.mesh_faceadr[mesh]), int(m.mesh_facenum[mesh])
                vert = np.asarray(m.mesh_vert[v0:v0 + nv], dtype=np.float64)  # in the geom frame
                face = np.asarray(m.mesh_face[f0:f0 + nf], dtype=np.int64)
                parts.append((int(g), vert, face, _vertex_normals(vert, face)))
            if parts and sum(len(v) for _, v, _, _ in parts) <= self.merge_meshes:
                # Small meshes: one entity, its vertices moved here every step (one Rerun call a
                # step instead of a transform per mesh; a few KiB a step more in the file).
                entity = f"{prefix}/meshes"
                vg = np.concatenate([np.full(len(v), g) for g, v, _, _ in parts])
                offsets = np.cumsum([0] + [len(v) for _, v, _, _ in parts[:-1]])
                faces = np.concatenate([f + o for (_, _, f, _), o in zip(parts, offsets)])
                rec.log(entity, rr.Mesh3D.from_fields(triangle_indices=faces, vertex_colors=self._rgba[vg]),
                        static=True)
                self._merged.append((entity, vg, np.concatenate([v for _, v, _, _ in parts]),
                                     np.concatenate([n for _, _, _, n in parts])))
                continue
            for g, vert, face, normals in parts:  # large ones: static meshes, moved by a transform
                entity = f"{prefix}/mesh/{rr.escape_entity_path_part(self._name(g))}"
                rec.log(entity, rr.Mesh3D(vertex_positions=vert, triangle_indices=face, vertex_normals=normals,
                                          albedo_factor=self._rgba[g]), static=True)
                self._meshes.append((entity, g))
        # Series styles, static: names and colours of the lines in the plots.
        for entity, colour, name in (
                ("stats/pairs/candidates", _CANDIDATE, "our candidates"),
                ("stats/pairs/mujoco_candidates", (120, 120, 120, 255), "MuJoCo broad-phase candidates"),
                ("stats/pairs/mujoco_contact_pairs", _MUJOCO, "MuJoCo contact pairs"),
                ("stats/pairs/missed", _MISSED, "MuJoCo contact pairs missed"),
                ("stats/contacts/mujoco", _MUJOCO, "MuJoCo contact points"),
                ("stats/contacts/collide", _OURS, "our contact points"),
                ("stats/contacts/missed", _MISSED, "MuJoCo contact points of pairs we missed"),
                ("stats/time_us/collide_broad", _CANDIDATE, "our broad phase"),
                ("stats/time_us/collide_contacts", _OURS, "our broad + narrow phase"),
                ("stats/time_us/mujoco_broad", _MUJOCO, "MuJoCo broad phase")):
            if self.contacts or not entity.endswith(("contacts/collide", "contacts/missed", "collide_contacts")):
                rec.log(entity, rr.SeriesLines(colors=[colour], names=[name]), static=True)
        # Styles of the per-step entities, static: a step logs positions only.
        for prefix in ("world/bounds/geom", "world/bounds/body"):
            rec.log(f"{prefix}_obbs", rr.Boxes3D.from_fields(radii=0.001, fill_mode="majorwireframe"), static=True)
            rec.log(f"{prefix}_spheres", rr.Ellipsoids3D.from_fields(colors=_SPHERE, line_radii=0.0006,
                                                                     fill_mode="majorwireframe"), static=True)
        rec.log("world/pairs/candidates", rr.LineStrips3D.from_fields(radii=0.0015, colors=_CANDIDATE), static=True)
        rec.log("world/pairs/missed", rr.LineStrips3D.from_fields(radii=0.006, colors=_MISSED), static=True)
        for entity, colour, r in (("world/contacts/mujoco", _MUJOCO, 0.006), ("world/contacts/collide", _OURS, 0.0045)):
            if self.contacts or entity == "world/contacts/mujoco":
                rec.log(entity, rr.Points3D.from_fields(radii=r, colors=colour),
                        rr.Arrows3D.from_fields(radii=r / 3, colors=colour), static=True)
        if self.contacts:  # contacts=False: ours are not computed, so none are missed either
            rec.log("world/contacts/missed", rr.Points3D.from_fields(radii=0.012, colors=_MISSED), static=True)

    def _name(self, g: int) -> str:
        adr = int(self.model.name_geomadr[g])
        names = bytes(self.model.names)
        name = names[adr:names.index(b"\0", adr)].decode() if adr >= 0 else ""
        return f"{g}_{name or 'geom'}"  # the id first: unique even where names repeat or are missing

    def _static_group(self, entity: str, t: int, ids: np.ndarray) -> None:
        # What never changes (sizes, colours) is logged once, static; a step logs the poses only.
        rr, s, colours = self.rr, self._size[ids], self._rgba[ids]
        if t == _T["box"]:
            arch = rr.Boxes3D.from_fields(half_sizes=s, colors=colours, fill_mode="solid")
        elif t == _T["plane"]:
            # A plane's size is visual only (0: infinite); drawn as a flat box of that size.
            half = np.where(s[:, :2] > 0, s[:, :2], 2.0 * self._extent)
            arch = rr.Boxes3D.from_fields(half_sizes=np.column_stack([half, np.zeros(len(ids))]), colors=colours,
                                          fill_mode="solid")
        elif t == _T["sphere"]:
            arch = rr.Ellipsoids3D.from_fields(half_sizes=np.repeat(s[:, :1], 3, axis=1), colors=colours,
                                               fill_mode="solid")
        elif t == _T["ellipsoid"]:
            arch = rr.Ellipsoids3D.from_fields(half_sizes=s, colors=colours, fill_mode="solid")
        elif t == _T["cylinder"]:
            arch = rr.Cylinders3D.from_fields(lengths=2.0 * s[:, 1], radii=s[:, 0], colors=colours, fill_mode="solid")
        else:
            arch = rr.Capsules3D.from_fields(lengths=2.0 * s[:, 1], radii=s[:, 0], colors=colours, fill_mode="solid")
        self.rec.log(entity, arch, static=True)

    def _log_geoms(self, gpos: np.ndarray, gmat: np.ndarray) -> None:
        rr, rec, size = self.rr, self.rec, self._size
        quat = _quat_xyzw(gmat) if self._groups else None  # one call for every geom (numpy's per-call cost)
        for entity, t, ids in self._groups:
            pos, rot = gpos[ids], gmat[ids]
            q = quat[ids]
            if t in (_T["box"], _T["plane"]):
                arch = rr.Boxes3D.from_fields(centers=pos, quaternions=q)
            elif t in (_T["sphere"], _T["ellipsoid"]):
                arch = rr.Ellipsoids3D.from_fields(centers=pos, quaternions=q)
            elif t == _T["cylinder"]:
                arch = rr.Cylinders3D.from_fields(centers=pos, quaternions=q)
            else:  # capsule: Rerun's runs from its origin along +z; MuJoCo's is centred
                arch = rr.Capsules3D.from_fields(translations=pos - rot[:, :, 2] * size[ids, 1:2], quaternions=q)
            rec.log(entity, arch)
        for entity, vg, vert, normals in self._merged:
            rot = gmat[vg]
            rec.log(entity, rr.Mesh3D.from_fields(vertex_positions=np.einsum("vij,vj->vi", rot, vert) + gpos[vg],
                                                  vertex_normals=np.einsum("vij,vj->vi", rot, normals)))
        for entity, g in self._meshes:
            if self._deferred is None:
                rec.log(entity, rr.Transform3D(translation=gpos[g], mat3x3=gmat[g]))
            else:  # replayed states: sent as columns after them
                steps, translation, mat = self._poses.setdefault(entity, ([], [], []))
                steps.append(self._deferred)
                translation.append(gpos[g].copy())
                mat.append(gmat[g].copy())

    def _log_bounds(self, prefix: str, wb, keep: np.ndarray, colours) -> int:
        rr, rec = self.rr, self.rec
        rec.log(f"{prefix}_obbs", rr.Boxes3D.from_fields(half_sizes=wb.obb_half[keep], centers=wb.obb_center[keep],
                                                         quaternions=_quat_xyzw(wb.obb_rot[keep]), colors=colours))
        r = wb.sphere_radius[keep]
        rec.log(f"{prefix}_spheres", rr.Ellipsoids3D.from_fields(half_sizes=np.repeat(r[:, None], 3, axis=1),
                                                                 centers=wb.sphere_center[keep]))
        return int(np.count_nonzero(keep))

    def _segments(self, pairs: np.ndarray, gpos: np.ndarray, gmat: np.ndarray) -> np.ndarray:
        # A line between the two geoms' centres; a plane's end is the foot of the other centre on it.
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        a, b = gpos[pairs[:, 0]].copy(), gpos[pairs[:, 1]].copy()
        plane = np.asarray(self.model.geom_type) == _T["plane"]
        for end, other, col in ((a, b, 0), (b, a, 1)):
            rows = np.flatnonzero(plane[pairs[:, col]])
            if len(rows):
                g = pairs[rows, col]
                n = gmat[g, :, 2]
                end[rows] = other[rows] - n * np.einsum("ij,ij->i", other[rows] - gpos[g], n)[:, None]
        return np.stack([a, b], axis=1)

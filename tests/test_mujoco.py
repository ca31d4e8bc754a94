"""The MuJoCo adapter: MuJoCo 4's filter rules on small models, every geom type, real scenes.

Rule tests build MJCF models whose geoms touch (or sit at a known distance), run MuJoCo's own
collision (``mj_forward``) and demand: MuJoCo's contact pairs are the pairs its rules allow
(the expectation is written out by name), and our candidates are exactly those pairs, no fewer
(recall) and no more (a pair MuJoCo's rules forbid is never proposed).
"""

import json
import math
from pathlib import Path

import mujoco
import numba
import numpy as np
import pytest

import collide
import collide.mujoco as cm
from collide._kernels import _quat
from collide._kernels import kinematics as _kin
from collide._kernels._simd import LANES

MODELS = Path(__file__).resolve().parents[1] / ".." / "shared" / "models"
SCENES = sorted(p.name for p in MODELS.iterdir() if (p / "scene.xml").is_file()) if MODELS.is_dir() else []


def _names(model, pairs) -> set:
    """Geom pairs as a set of frozensets of geom names."""
    return {frozenset((model.geom(int(a)).name, model.geom(int(b)).name)) for a, b in pairs}


def _both(xml: str):
    """MuJoCo's contact pairs and our candidates, by name, at the model's initial state."""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ours = cm.BroadPhase(model).pairs(data)
    assert ours.dtype == np.int32 and ours.ndim == 2 and ours.shape[1] == 2
    return _names(model, cm.contact_pairs(model, data)), _names(model, ours), model


def _pairs(*names: str) -> set:
    return {frozenset(p.split("-")) for p in names}


# ----------------------------------------------------------------------------------- filters

CLUSTER = """<mujoco><worldbody>{}</worldbody></mujoco>"""


def _free_sphere(name, pos, extra=""):
    return (f'<body name="{name}" pos="{pos}"><freejoint/>'
            f'<geom name="{name}" type="sphere" size=".1" {extra}/></body>')


def test_contype_conaffinity():
    # Five spheres within 0.1 of each other: every pair touches; only the masks decide.
    masks = {"a": (1, 1), "b": (2, 2), "c": (2, 1), "d": (0, 0), "e": (4, 3)}
    offs = ["0 0 0", ".05 0 0", "0 .05 0", "0 0 .05", ".03 .03 .03"]
    body = "".join(_free_sphere(n, o, f'contype="{ct}" conaffinity="{ca}"')
                   for (n, (ct, ca)), o in zip(masks.items(), offs))
    mj, ours, _ = _both(CLUSTER.format(body))
    # (ct1 & ca2) or (ct2 & ca1): a-c (ct_c=2 & ca_a=1 no; ct_a=1 & ca_c=1 yes), b-c, e-a, e-c, e-b
    expected = _pairs("a-c", "b-c", "a-e", "b-e", "c-e")
    assert mj == expected
    assert ours == expected
    model = mujoco.MjModel.from_xml_string(CLUSTER.format(body))
    assert repr(cm.BroadPhase(model)) == "collide.mujoco.BroadPhase(6 bodies, 5 geoms)"


CHAIN = """<mujoco><option><flag filterparent="{fp}"/></option><worldbody>
  <geom name="w" type="sphere" size=".1" pos="0 0 -.05"/>
  <body name="a"><freejoint/><geom name="a" type="sphere" size=".1"/>
    <body name="b" pos=".05 0 0"><joint type="hinge"/><geom name="b" type="sphere" size=".1"/>
      <body name="c" pos=".05 0 0"><joint type="hinge"/><geom name="c" type="sphere" size=".1"/>
      </body></body></body>
</worldbody></mujoco>"""


def test_parent_child_filter():
    mj, ours, _ = _both(CHAIN.format(fp="enable"))
    # a-b and b-c are parent-child; a-c are not; the world is never filtered as a parent.
    expected = _pairs("a-c", "w-a", "w-b", "w-c")
    assert mj == expected
    assert ours == expected


def test_parent_child_filter_disabled():
    mj, ours, _ = _both(CHAIN.format(fp="disable"))
    expected = _pairs("a-b", "b-c", "a-c", "w-a", "w-b", "w-c")
    assert mj == expected
    assert ours == expected


WELD = """<mujoco><option><flag filterparent="{fp}"/></option><worldbody>
  <geom name="w" type="sphere" size=".1" pos="0 0 -.05"/>
  <body name="s1" pos=".05 .05 0"><geom name="s1" type="sphere" size=".1"/></body>
  <body name="s2" pos="-.05 .05 0"><geom name="s2" type="sphere" size=".1"/></body>
  <body name="a"><freejoint/><geom name="a" type="sphere" size=".1"/>
    <body name="b" pos=".05 0 0"><geom name="b" type="sphere" size=".1"/>
      <body name="c" pos=".05 0 0"><joint type="hinge"/><geom name="c" type="sphere" size=".1"/>
      </body></body></body>
</worldbody></mujoco>"""


def test_weld_groups():
    # s1, s2 are static (welded to the world, group 0): never with each other or the world.
    # b has no joint: welded to a (never a-b); c's weld parent is then a's group, so the
    # parent filter removes c-a and c-b alike. b pairs with what a pairs with.
    mj, ours, model = _both(WELD.format(fp="enable"))
    assert model.body_weldid[model.body("b").id] == model.body_weldid[model.body("a").id]
    expected = _pairs("w-a", "w-b", "w-c", "s1-a", "s1-b", "s1-c", "s2-a", "s2-b", "s2-c")
    assert mj == expected
    assert ours == expected
    mj, ours, _ = _both(WELD.format(fp="disable"))
    expected |= _pairs("a-c", "b-c")
    assert mj == expected
    assert ours == expected


def test_static_parent_is_not_filtered():
    # A jointed body under a static body (weld group 0): MuJoCo exempts the world's group from
    # the parent filter, so they pair, though the parent is not body 0. Our rule set must then
    # fall back to explicit exclusions.
    xml = """<mujoco><worldbody>
      <body name="st" pos="0 0 1"><geom name="st" type="sphere" size=".1"/>
        <body name="c" pos=".15 0 0"><joint type="hinge"/><geom name="c" type="sphere" size=".1"/>
          <body name="g" pos=".15 0 0"><joint type="hinge"/><geom name="g" type="sphere" size=".1"/>
          </body></body></body>
    </worldbody></mujoco>"""
    mj, ours, model = _both(xml)
    assert mj == ours == _pairs("st-c")
    filter_parent, _ = cm.exclusion_rules(model, cm.weld_groups(model))
    assert not filter_parent


def test_child_of_world_pairs_with_world_geoms():
    xml = """<mujoco><worldbody>
      <geom name="w1" type="box" size=".1 .1 .1"/>
      <body name="a" pos="0 0 .15"><joint type="slide" axis="0 0 1"/>
        <geom name="a" type="sphere" size=".1"/></body>
    </worldbody></mujoco>"""
    mj, ours, _ = _both(xml)
    assert mj == ours == _pairs("w1-a")


def test_exclude():
    body = (_free_sphere("a", "0 0 0") + _free_sphere("b", ".05 0 0")
            + _free_sphere("c", "0 .05 0"))
    xml = f"""<mujoco><worldbody>{body}</worldbody>
      <contact><exclude body1="a" body2="b"/></contact></mujoco>"""
    mj, ours, _ = _both(xml)
    assert mj == ours == _pairs("a-c", "b-c")


def test_explicit_pairs_bypass_filters_and_use_their_margin():
    # Surfaces 0.05 apart; contype 0 so no dynamic pair. Explicit pairs: margin .06 reaches,
    # margin .04 does not, and a pair across a parent-child link (which the parent filter and
    # the masks would both forbid) with its own margin reaches.
    xml = """<mujoco><worldbody>
      <body name="a"><freejoint/><geom name="a" type="sphere" size=".1" contype="0" conaffinity="0"/>
        <body name="a2" pos="0 0 .25"><joint type="hinge"/>
          <geom name="a2" type="sphere" size=".1" contype="0" conaffinity="0"/></body></body>
      <body name="b" pos=".25 0 0"><freejoint/><geom name="b" type="sphere" size=".1" contype="0" conaffinity="0"/></body>
      <body name="c" pos="-.25 0 0"><freejoint/><geom name="c" type="sphere" size=".1" contype="0" conaffinity="0"/></body>
    </worldbody><contact>
      <pair geom1="a" geom2="b" margin=".06"/>
      <pair geom1="a" geom2="c" margin=".04"/>
      <pair geom1="a" geom2="a2" margin=".03" gap=".03"/>
    </contact></mujoco>"""
    mj, ours, _ = _both(xml)
    assert mj == _pairs("a-b", "a-a2")
    assert ours == mj


def test_explicit_pair_replaces_the_dynamic_pair():
    # Surfaces 0.05 apart; the geoms' own margins (0.03 each) would make a contact, but an
    # explicit pair of the same geoms takes over with its own, smaller margin: no contact.
    xml = """<mujoco><worldbody>
      <body name="a"><freejoint/><geom name="a" type="sphere" size=".1" margin=".03"/></body>
      <body name="b" pos=".25 0 0"><freejoint/><geom name="b" type="sphere" size=".1" margin=".03"/></body>
      <body name="c" pos="-.25 0 0"><freejoint/><geom name="c" type="sphere" size=".1" margin=".03"/></body>
    </worldbody><contact><pair geom1="b" geom2="a" margin=".01"/></contact></mujoco>"""
    mj, ours, _ = _both(xml)
    assert mj == ours == _pairs("a-c")


def test_bodies_dynamics_never_moves_never_pair():
    # Mocap bodies, static bodies and the world have no degrees of freedom (body_treeid < 0):
    # MuJoCo 4 makes no contact between two of them, though m1's weld group is its own. A body
    # with a joint under a mocap body is its child (parent filter) but pairs with the rest;
    # an explicit pair between two of them still makes contacts.
    xml = """<mujoco><worldbody>
      <geom name="w" type="sphere" size=".1"/>
      <body name="m1" mocap="true" pos=".05 0 0"><geom name="m1" type="sphere" size=".1"/>
        <body name="mc" pos="0 .05 0"><joint/><geom name="mc" type="sphere" size=".1"/></body></body>
      <body name="m2" mocap="true" pos="0 .05 0"><geom name="m2" type="sphere" size=".1"/></body>
      <body name="st" pos="0 0 .05"><geom name="st" type="sphere" size=".1"/></body>
      <body name="f" pos=".03 .03 .03"><freejoint/><geom name="f" type="sphere" size=".1"/></body>
    </worldbody><contact><pair geom1="st" geom2="m2"/></contact></mujoco>"""
    mj, ours, model = _both(xml)
    assert model.body_weldid[model.body("m1").id] != 0
    expected = _pairs("f-w", "f-m1", "f-m2", "f-st", "f-mc", "mc-w", "mc-m2", "mc-st", "st-m2")
    assert mj == expected
    assert ours == expected


def test_margin_and_gap():
    # Surfaces 0.05 apart: a contact is generated below margin1 + margin2 + gap1 + gap2.
    for margin, gap, touch in [(0.02, 0.0, False), (0.03, 0.0, True), (0.02, 0.01, True),
                               (0.0, 0.03, True), (0.01, 0.01, False)]:
        extra = f'margin="{margin}" gap="{gap}"'
        xml = CLUSTER.format(_free_sphere("a", "0 0 0", extra) + _free_sphere("b", ".25 0 0", extra))
        mj, ours, _ = _both(xml)
        expected = _pairs("a-b") if touch else set()
        assert mj == expected, (margin, gap)
        assert ours == expected, (margin, gap)


def test_margin_override():
    xml = """<mujoco><option o_margin=".06"><flag override="enable"/></option><worldbody>{}</worldbody></mujoco>"""
    mj, ours, _ = _both(xml.format(_free_sphere("a", "0 0 0") + _free_sphere("b", ".25 0 0")))
    assert mj == ours == _pairs("a-b")


def test_plane_is_a_halfspace():
    # A floor and a tilted plane on a static body; spheres touching, above, and far out on the
    # floor (the plane's size is visual only: it is an infinite half-space for collisions).
    xml = """<mujoco><worldbody>
      <geom name="floor" type="plane" size=".5 .5 .1"/>
      <body name="wall" pos="3 0 0" euler="0 -90 0"><geom name="wall" type="plane" size="1 1 .1"/></body>
      <body name="on"  pos="0 0 .09"><freejoint/><geom name="on" type="sphere" size=".1"/></body>
      <body name="far" pos="20 20 .05"><freejoint/><geom name="far" type="box" size=".1 .1 .1"/></body>
      <body name="up"  pos="0 1 .5"><freejoint/><geom name="up" type="sphere" size=".1"/></body>
      <body name="nearwall" pos="2.95 0 1"><freejoint/><geom name="nearwall" type="capsule" size=".1 .2"/></body>
    </worldbody></mujoco>"""
    mj, ours, _ = _both(xml)
    # "far" is beyond the tilted wall's half-space boundary x = 3 too (x = 20 > 3 - 0.1).
    expected = _pairs("floor-on", "floor-far", "wall-nearwall", "wall-far")
    assert mj == expected
    assert ours == expected


def test_contacts_disabled():
    xml = """<mujoco><option><flag contact="disable"/></option><worldbody>{}</worldbody></mujoco>"""
    mj, ours, model = _both(xml.format(_free_sphere("a", "0 0 0") + _free_sphere("b", ".05 0 0")))
    assert mj == ours == set()
    assert cm.BroadPhase(model).pairs_batch(model, np.zeros((3, model.nq))).shape == (0, 3)


# ----------------------------------------------------------------------------------- geom types

TYPES = """<mujoco><asset>
  <mesh name="tet" vertex="0 0 0  .2 0 0  0 .2 0  0 0 .2  .05 .05 .05"/>
  <hfield name="hf" nrow="3" ncol="3" size=".5 .5 .1 .05" elevation="0 0 0 0 1 0 0 0 0"/>
</asset><worldbody>
  <geom name="floor" type="plane" size="2 2 .1"/>
  <geom name="hfield" type="hfield" hfield="hf" pos="3 0 0"/>
  <body name="sphere" pos="0 0 .099"><freejoint/><geom name="sphere" type="sphere" size=".1"/></body>
  <body name="capsule" pos=".4 0 .05" euler="90 0 0"><freejoint/><geom name="capsule" type="capsule" size=".05 .2"/></body>
  <body name="ellipsoid" pos=".8 0 .049"><freejoint/><geom name="ellipsoid" type="ellipsoid" size=".2 .1 .05"/></body>
  <body name="cylinder" pos="1.2 0 .049" euler="0 90 45"><freejoint/><geom name="cylinder" type="cylinder" size=".05 .2"/></body>
  <body name="box" pos="0 .6 .1" euler="30 0 0"><freejoint/><geom name="box" type="box" size=".1 .1 .1"/></body>
  <body name="mesh" pos=".6 .6 -.001"><freejoint/><geom name="mesh" type="mesh" mesh="tet"/></body>
  <body name="onhf" pos="3 0 .13"><freejoint/><geom name="onhf" type="sphere" size=".05"/></body>
  <body name="pile" pos="1.2 .6 .1"><freejoint/><geom name="pile" type="box" size=".1 .1 .1"/></body>
  <body name="pile2" pos="1.2 .6 .199"><freejoint/><geom name="pile2" type="mesh" mesh="tet" euler="0 0 30"/></body>
</worldbody></mujoco>"""


def test_every_geom_type_touching():
    mj, ours, model = _both(TYPES)
    expected = _pairs("floor-sphere", "floor-capsule", "floor-ellipsoid", "floor-cylinder",
                      "floor-box", "floor-mesh", "hfield-onhf", "floor-pile", "pile-pile2")
    assert mj == expected
    # Every MuJoCo contact is ours; plane-hfield (no collision function in MuJoCo) is not.
    assert mj <= ours
    assert frozenset(("floor", "hfield")) not in ours
    # Our extra candidates, if any, are bound-level near misses, never forbidden pairs.
    for pair in ours - mj:
        assert "hfield" not in pair or "floor" not in pair


SDF = """<mujoco><extension><plugin plugin="mujoco.sdf.torus"><instance name="torus">
    <config key="radius1" value="0.35"/><config key="radius2" value="0.15"/></instance></plugin>
  </extension><asset><mesh name="torus"><plugin instance="torus"/></mesh></asset>
  <option sdf_iterations="10" sdf_initpoints="20"/>
  <worldbody><geom name="floor" type="plane" size="2 2 .1"/>
    <body name="torus" pos="0 0 .149"><freejoint/>
      <geom name="torus" type="sdf" mesh="torus"><plugin instance="torus"/></geom></body>
    <body name="ball" pos=".35 0 .398"><freejoint/><geom name="ball" type="sphere" size=".1"/></body>
    <body name="side" pos=".599 0 .149"><freejoint/><geom name="side" type="sphere" size=".1"/></body>
  </worldbody></mujoco>"""


def test_sdf_geom_is_bounded_by_its_padded_box():
    # A torus (plugin SDF) resting on the floor, a ball on its top and one touching its outer
    # rim (true extent 0.5; MuJoCo's own box stops at 0.49995).
    try:
        mj, ours, model = _both(SDF)
    except ValueError as exc:  # a MuJoCo build without its SDF plugins
        pytest.skip(f"mujoco.sdf.torus plugin not available: {exc}")
    expected = _pairs("floor-torus", "ball-torus", "side-torus")
    assert mj == expected
    assert ours == expected


def test_mesh_cloud_is_the_geom_frame_hull():
    # The mesh's vertices as MuJoCo stores them lie in the geom frame: its own geom_aabb holds
    # them, and the geom's world points from our cloud match MuJoCo's world AABB corners.
    model = mujoco.MjModel.from_xml_string(TYPES)
    clouds = cm.geom_clouds(model)
    g = model.geom("mesh").id
    pts = clouds[g].points
    c, h = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
    assert np.all(np.abs(pts - c) <= h + 1e-6)
    np.testing.assert_allclose(pts.min(axis=0), c - h, atol=1e-6)
    np.testing.assert_allclose(pts.max(axis=0), c + h, atol=1e-6)


def test_inflation_values():
    xml = """<mujoco><worldbody>
      <body><freejoint/><geom name="a" type="sphere" size=".1" margin=".02" gap=".01"/></body>
      <body><freejoint/><geom name="b" type="sphere" size=".1"/></body>
    </worldbody><contact><pair geom1="a" geom2="b" margin=".05" gap=".02"/></contact></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    # every geom adds ccd_tolerance (see test_ccd_tolerance_widens_the_bounds), each of a pair's two too
    tol = model.opt.ccd_tolerance
    assert tol == 1e-6
    np.testing.assert_allclose(cm.geom_inflation(model), [0.03 + tol, tol], rtol=0, atol=1e-15)
    np.testing.assert_allclose(cm.pair_inflation(model), [0.07 + 2 * tol], rtol=0, atol=1e-15)


def _cylinder_and_box(scale: float, ccd_tolerance: str = ""):
    # A cylinder and a box 4.96e-3 * scale apart, which MuJoCo's GJK/EPA reports as touching
    # (dist -6.5e-3 * scale) when ccd_tolerance is 1e-2 * scale (review reproducer, 2026-11-21).
    opt = f'ccd_tolerance="{ccd_tolerance}"' if ccd_tolerance else ""
    inertial = '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'
    xml = f"""<mujoco><option gravity="0 0 0" {opt}/><worldbody>
      <body>{inertial}<freejoint/><geom type="cylinder" size="{.3 * scale} {.02 * scale}"/></body>
      <body>{inertial}<freejoint/><geom type="box" size="{.3 * scale} {.05 * scale} {.01 * scale}"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[:] = [-0.27354999853321776, 0.042656946555812425, 0.15046362590392015, 0.40528595143131513,
                    -0.15773661178624865, 0.3617266135643967, -0.8246310180400938, 0.11434286081098499,
                    0.22623580440450386, 0.08393490114742647, 0.7237705373703305, -0.5149749858364848,
                    -0.3230656425759032, 0.32647444583672086]
    data.qpos[0:3] *= scale
    data.qpos[7:10] *= scale
    mujoco.mj_forward(model, data)
    return model, data


@pytest.mark.parametrize("scale, tol", [(1.0, "0.01"), (1e-4, "")])
def test_ccd_tolerance_widens_the_bounds(scale, tol):
    # MuJoCo's convex narrow phase reports contacts up to ~0.8 x ccd_tolerance apart: we must
    # propose them (at 1e-4 scale the default 1e-6 tolerance is 1/30 of the box's width).
    model, data = _cylinder_and_box(scale, tol)
    assert cm.contact_pairs(model, data).tolist() == [[0, 1]]
    bp = cm.BroadPhase(model)
    ours = bp.pairs(data).tolist()
    model.opt.ccd_tolerance = 1e-12 * scale
    gap = mujoco.mj_geomDistance(model, data, 0, 1, 1.0, np.zeros(6))
    assert gap > 0.4e-2 * scale  # truly apart, by about half the tolerance
    assert ours == [[0, 1]]


def test_ccd_tolerance_widens_polytopes_when_gjk_stops_early():
    # With few GJK iterations MuJoCo reports polytopes up to ~0.8 x ccd_tolerance apart as touching
    # (a box and a mesh 0.0095 apart at 4 iterations, tolerance 0.1: review reproducer, 2026-11-22);
    # the tolerance once widened only ellipsoids and cylinders.
    xml = """<mujoco><option gravity="0 0 0" ccd_tolerance="0.1" ccd_iterations="4"/>
      <asset><mesh name="m" vertex="0.01 0.408 0.367 -0.153 -0.089 -0.158 0.171 -0.017 0.224 -0.554 0.47 -0.029
        0.204 -0.041 -0.114 0.139 0.247 -0.061 -0.046 0.206 -0.261 -0.454 0.118 -0.201"/></asset><worldbody>
      <body><freejoint/><geom type="box" size=".2 .2 .2"/></body>
      <body><freejoint/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[7:10] = [0.415, -0.108, -0.344]
    mujoco.mj_forward(model, data)
    assert cm.contact_pairs(model, data).tolist() == [[0, 1]]
    ours = cm.BroadPhase(model).pairs(data).tolist()
    model.opt.ccd_iterations, model.opt.ccd_tolerance = 1000, 1e-12
    assert mujoco.mj_geomDistance(model, data, 0, 1, 1.0, None) > 0.009  # truly apart
    assert ours == [[0, 1]]


def test_geoms_snapped_to_their_body_frame():
    # The compiler snaps a geom within its tolerance of the body (or inertial) frame to it
    # (geom_sameframe) and mj_kinematics then ignores geom_pos: a plane 5e-7 below the origin
    # is at the origin, and a box resting on z = 0 touches it (review reproducer, 2026-11-21).
    # (A tiny box and tolerance: our rotation slack and ccd_tolerance inflation would hide it.)
    xml = """<mujoco><option gravity="0 0 0" ccd_tolerance="1e-10"/><worldbody>
      <geom type="plane" size="1 1 1" pos="0 0 -5e-7"/>
      <body pos="0 0 1e-7"><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>
        <geom type="box" size="1e-3 1e-3 2e-7"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert model.geom_sameframe[0] == mujoco.mjtSameFrame.mjSAMEFRAME_BODY and model.geom_pos[0, 2] == -5e-7
    assert cm.contact_pairs(model, data).tolist() == [[0, 1]]
    assert cm.BroadPhase(model).pairs(data).tolist() == [[0, 1]]


def test_geom_frames_follow_mj_kinematics():
    # Every kind of geom_sameframe, on a body with an offset, rotated inertial frame.
    xml = """<mujoco><worldbody><body pos=".3 -.2 1" euler="10 20 30"><freejoint/>
      <inertial pos=".1 .2 .3" euler="40 50 60" mass="1" diaginertia="1 2 3"/>
      <geom name="none" size=".1" pos=".5 0 0" euler="5 6 7"/>
      <geom name="body" size=".1"/>
      <geom name="inertia" size=".1" pos=".1 .2 .3" euler="40 50 60"/>
      <geom name="bodyrot" size=".1" pos="1 1 1"/>
      <geom name="inertiarot" size=".1" pos="-.4 .1 0" euler="40 50 60"/>
    </body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    assert sorted(model.geom_sameframe) == [0, 1, 2, 3, 4]
    data = mujoco.MjData(model)
    data.qpos[3:7] = [0.5, 0.5, -0.5, 0.5]
    mujoco.mj_kinematics(model, data)
    pos, rot = cm.geom_frames(model)
    for g in range(model.ngeom):
        b = model.geom_bodyid[g]
        R = data.xmat[b].reshape(3, 3)
        np.testing.assert_allclose(data.xpos[b] + R @ pos[g], data.geom_xpos[g], atol=1e-12)
        np.testing.assert_allclose(R @ rot[g], data.geom_xmat[g].reshape(3, 3), atol=1e-12)


def test_another_models_data_or_model_is_refused():
    # Same body and geom counts, other geometry: an answer would be silently wrong.
    a = CLUSTER.format('<geom type="plane" size="1 1 1"/>' + _free_sphere("a", "0 0 .05")
                       + _free_sphere("b", "1 0 .05"))
    b = CLUSTER.format(_free_sphere("a", "0 0 3") + '<body pos="0 0 3.1"><freejoint/>'
                       '<geom size=".1" contype="0" conaffinity="0"/><geom size=".1" pos="0 .1 0"/></body>')
    ma, mb = mujoco.MjModel.from_xml_string(a), mujoco.MjModel.from_xml_string(b)
    assert (ma.nbody, ma.ngeom) == (mb.nbody, mb.ngeom)
    bp = cm.BroadPhase(ma)
    db = mujoco.MjData(mb)
    mujoco.mj_forward(mb, db)
    with pytest.raises(ValueError, match="data: made for another model"):
        bp.pairs(db)
    with pytest.raises(ValueError, match="data: made for another model"):
        bp.world_bounds(db)  # as pairs() (it answered for the other model; review, 2026-11-22)
    with pytest.raises(ValueError, match="model: not the model this BroadPhase was built from"):
        bp.pairs_batch(mb, mb.qpos0[None])
    with pytest.raises(ValueError, match="broadphase: built from another model"):
        cm.compare(mb, steps=2, broadphase=bp)
    # a second copy of the same model is the same model
    twin = mujoco.MjModel.from_xml_string(a)
    dt = mujoco.MjData(twin)
    mujoco.mj_forward(twin, dt)
    assert bp.pairs(dt).tolist() == cm.BroadPhase(twin).pairs(dt).tolist()
    assert len(bp.pairs_batch(twin, twin.qpos0[None])) == 2


def _batch_equals_single_worlds(bp, model, qpos) -> int:
    # pairs_batch(model, qpos) row by row against pairs(data) after mj_kinematics; the pair count.
    batch = bp.pairs_batch(model, qpos)
    data = mujoco.MjData(model)
    total = 0
    for w in range(len(qpos)):
        data.qpos[:] = qpos[w]
        mujoco.mj_kinematics(model, data)
        single = bp.pairs(data)
        np.testing.assert_array_equal(batch[batch[:, 0] == w, 1:], single)
        total += len(single)
    assert len(batch) == total
    return total


def test_pairs_batch_equals_single_worlds():
    model = mujoco.MjModel.from_xml_string(CHAIN.format(fp="enable"))
    bp = cm.BroadPhase(model)
    rng = np.random.default_rng(3)
    qpos = np.tile(model.qpos0, (6, 1))
    qpos[:, :3] += rng.uniform(-0.3, 0.3, size=(6, 3))
    qpos[:, 7:] = rng.uniform(-2, 2, size=(6, model.nq - 7))
    assert _batch_equals_single_worlds(bp, model, qpos) > 0
    with pytest.raises(ValueError, match="qpos"):
        bp.pairs_batch(model, np.zeros((2, model.nq + 1)))


def _random_qpos(model, worlds, rng):
    """Configurations around qpos0: joints moved within +-1.5 rad / 0.3 m, random orientations."""
    q = np.tile(model.qpos0, (worlds, 1))
    for j in range(model.njnt):
        a, t = model.jnt_qposadr[j], model.jnt_type[j]
        if t == mujoco.mjtJoint.mjJNT_FREE:
            q[:, a:a + 3] += rng.uniform(-0.3, 0.3, size=(worlds, 3))
            q[:, a + 3:a + 7] = rng.normal(size=(worlds, 4)) * rng.uniform(0.5, 2.0, size=(worlds, 1))
        elif t == mujoco.mjtJoint.mjJNT_BALL:
            q[:, a:a + 4] = rng.normal(size=(worlds, 4))
        elif t == mujoco.mjtJoint.mjJNT_SLIDE:
            q[:, a] += rng.uniform(-0.3, 0.3, size=worlds)
        else:
            q[:, a] += rng.uniform(-1.5, 1.5, size=worlds)
    return q


KIN = """<mujoco><worldbody>
  <body name="m" mocap="true" pos="0 1 0" quat="0.9 0.1 0 0.2"><geom size=".1"/></body>
  <body name="a" pos="0 0 1" euler="10 20 30"><freejoint/><geom size=".1"/>
    <body name="b" pos=".2 0 0" euler="0 30 0"><joint type="hinge" axis="0 1 1" pos=".05 0 0"/>
      <joint type="slide" axis="1 0 0"/><geom size=".1"/>
      <body name="c" pos=".2 .1 0"><joint type="ball" pos="0 0 .1"/><geom size=".1"/>
        <body name="d" pos="0 0 .2" quat="0 1 0 0"><geom size=".1"/></body></body></body></body>
</worldbody></mujoco>"""
# KIN with both turning joints anchored at their body's origin and body b unrotated in a: the
# kinematics' shortcuts (`_quat._turn`, `_quat._unit_quat`), beside KIN's general steps.
KIN_ORIGIN = (KIN.replace(' pos=".05 0 0"', "").replace('<joint type="ball" pos="0 0 .1"/>', '<joint type="ball"/>')
              .replace(' euler="0 30 0"', ""))


def _kin_model(name):
    return mujoco.MjModel.from_xml_string(KIN if name == "kinematics_mjcf" else KIN_ORIGIN)


@pytest.mark.parametrize("xml", ["chain", "kinematics_mjcf"])
def test_pairs_batch_poses_in_the_call_equal_kinematics_then_batch(xml):
    # On a small model pairs_batch(model, qpos) computes each group of worlds' poses in the lane
    # kernel's own call (`_kernels.kinematics.step_lanes_kin`): its rows and stats must be those of
    # kinematics_batch followed by collide.BroadPhase.pairs_batch, bit for bit, over full and
    # partial groups of lanes; a bad pose names the same world and body in both.
    # KIN's spheres grown from 0.1 to 0.25 so that its worlds have pairs (none at 0.1)
    model = mujoco.MjModel.from_xml_string(CHAIN.format(fp="enable") if xml == "chain"
                                           else KIN.replace('size=".1"', 'size=".25"'))
    bp = cm.BroadPhase(model)
    assert bp.broadphase.batch_path == "lanes"
    qpos = _random_qpos(model, 21, np.random.default_rng(11))
    got = bp.pairs_batch(model, qpos)
    stats = bp.stats
    want = bp.broadphase.pairs_batch(*cm.kinematics_batch(model, qpos))
    assert np.array_equal(got, want) and got.dtype == want.dtype
    assert bp.stats == stats and stats["pairs"] == len(got)
    assert len(np.unique(got[:, 0])) > 10  # hits in most worlds (chain 21, KIN 19 of 21)
    if xml == "kinematics_mjcf":  # every joint type, a mocap body; and a bad pose
        slide = model.jnt_qposadr[np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE)[0]]
        qpos[13, slide] = 1e200  # body b and its children beyond MAX_POSITION, in world 13
        for call in (lambda: bp.pairs_batch(model, qpos),
                     lambda: bp.broadphase.pairs_batch(*cm.kinematics_batch(model, qpos))):
            with pytest.raises(ValueError, match=r"world 13, body 3: "):
                call()
        qpos[13, slide] = 0.0
        again = bp.pairs_batch(model, qpos)
        assert len(again) > 0 and np.array_equal(again, bp.broadphase.pairs_batch(*cm.kinematics_batch(model, qpos)))


def test_pairs_batch_sees_the_models_arrays_changed_in_place():
    # pairs_batch keeps views of the model's arrays between calls (made once per MjModel): a body
    # pose or qpos0 changed in place must reach the next call, as it reaches mj_kinematics.
    model = mujoco.MjModel.from_xml_string(KIN.replace('size=".1"', 'size=".25"'))
    bp = cm.BroadPhase(model)
    assert bp.broadphase.batch_path == "lanes"
    qpos = _random_qpos(model, 9, np.random.default_rng(3))
    before = bp.pairs_batch(model, qpos)
    assert len(before) > 0
    b = model.body("b").id
    slide = model.jnt_qposadr[np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE)[0]]
    # b and its subtree moved far away: by its pose in its parent, then by its slide's reference
    for array, at, shift in ((model.body_pos, (b, 0), 5.0), (model.qpos0, slide, -5.0)):
        old = array[at]
        array[at] = old + shift
        got = bp.pairs_batch(model, qpos)
        assert np.array_equal(got, bp.broadphase.pairs_batch(*cm.kinematics_batch(model, qpos)))
        assert len(got) < len(before)
        array[at] = old
        assert np.array_equal(bp.pairs_batch(model, qpos), before)
    # a second MjModel of the same geometry, its body moved: each call reads the model it is given
    other = mujoco.MjModel.from_xml_string(KIN.replace('size=".1"', 'size=".25"'))
    other.body_pos[b, 0] += 5.0
    far = bp.pairs_batch(other, qpos)
    assert np.array_equal(far, bp.broadphase.pairs_batch(*cm.kinematics_batch(other, qpos)))
    assert len(far) < len(before)
    assert np.array_equal(bp.pairs_batch(model, qpos), before)


@pytest.mark.parametrize("kin", ["kinematics_mjcf", "anchors_at_origin"])
def test_pairs_batch_names_every_non_finite_qpos_entry(kin):
    # A float64 C-contiguous qpos goes to the lane kernel unchecked (`pairs_batch`): every NaN or
    # inf entry, of every joint type (free position and quaternion, hinge, slide, ball), must make
    # a pose the kernel refuses, and the error then names the qpos entry, as the full check does
    # for any other input (a list, a float32 or strided array). A hinge on a body without geoms
    # too (its pose is checked all the same), in a full group of lanes (world 3) and a partial one.
    # With the joints anchored at their bodies' origins (`_quat._turn`) a NaN angle leaves the
    # position finite, and the rotation alone carries it to the pose check.
    xml = (KIN if kin == "kinematics_mjcf" else KIN_ORIGIN).replace('size=".1"', 'size=".25"').replace(
        '<body name="d" pos="0 0 .2" quat="0 1 0 0"><geom size=".25"/></body>',
        '<body name="d" pos="0 0 .2" quat="0 1 0 0"><geom size=".25"/></body>'
        '<body name="e" pos="0 .2 0"><joint type="hinge" axis="1 0 0"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia=".1 .1 .1"/></body>')
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.nbody == 7 and model.body_geomnum[6] == 0 and model.body_jntnum[6] == 1
    bp = cm.BroadPhase(model)
    assert bp.broadphase.batch_path == "lanes"
    good = _random_qpos(model, 11, np.random.default_rng(5))
    assert len(bp.pairs_batch(model, good)) > 0
    for j in range(model.nq):
        for value in (np.nan, np.inf, -np.inf):
            for w in (3, 9):
                qpos = good.copy()
                qpos[w, j] = value
                for arg in (qpos, qpos.tolist(), np.asfortranarray(qpos)):
                    with pytest.raises(ValueError, match=rf"qpos: non-finite value \(NaN or inf\) at index \({w}, {j}\)"):
                        bp.pairs_batch(model, arg)
    assert np.array_equal(bp.pairs_batch(model, good), bp.broadphase.pairs_batch(*cm.kinematics_batch(model, good)))


def test_batch_kernels_leave_the_parallel_chunk_size_as_they_found_it():
    # Each batch kernel sets numba's chunk size to 1 for its own loop and puts the caller's back
    # (`_kernels._threads.set_chunksize`), on a good batch and on one with a bad world: the fused
    # kernel (pairs_batch on qpos), the lanes and the per-world kernel (collide.BroadPhase.pairs_batch
    # on poses), the kinematics (kinematics_batch).
    model = mujoco.MjModel.from_xml_string(CHAIN.format(fp="enable"))
    bp = cm.BroadPhase(model)
    assert bp.broadphase.batch_path == "lanes"  # the fused kernel runs it
    qpos = _random_qpos(model, 20, np.random.default_rng(2))
    bad = qpos.copy()
    bad[7, 0] = 1e200  # the free joint's x: every body beyond MAX_POSITION in world 7
    pos, rot = cm.kinematics_batch(model, qpos)
    per_world = collide.BroadPhase(cm.articulation(model), batch_path="worlds")  # step_batch, world by world
    before = numba.get_parallel_chunksize()
    try:
        numba.set_parallel_chunksize(5)
        calls = [lambda q: bp.pairs_batch(model, q),
                 lambda q: bp.broadphase.pairs_batch(*cm.kinematics_batch(model, q)),
                 lambda q: per_world.pairs_batch(*cm.kinematics_batch(model, q))]
        for call in calls:
            assert len(call(qpos)) > 0
            assert numba.get_parallel_chunksize() == 5
            with pytest.raises(ValueError, match="world 7, body 1: "):
                call(bad)
            assert numba.get_parallel_chunksize() == 5
        assert np.array_equal(cm.kinematics_batch(model, qpos)[0], pos)
        assert numba.get_parallel_chunksize() == 5
    finally:
        numba.set_parallel_chunksize(before)


# Not cached (no cache=True): numba stamps a test file's cache with that file alone, and these
# helpers inline the package's kernels, so after a change to `_kernels._quat` the cached helper kept
# the old code and this test compared old lanes with new worlds (found 2026-11-27: a 1-ulp mismatch
# that a fresh cache folder did not show). The package's own kernels are stamped with every file
# they import (`collide._cache`).
@numba.njit
def _lane_poses(qp, arrays, ps, scratch):
    # every group of LANES worlds of qp through `_kinematics_lanes`, into ps (groups, L, 12, LANES)
    (q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis) = arrays
    for g in range(ps.shape[0]):
        g0 = g * LANES
        _kin._kinematics_lanes(qp, g0, min(LANES, qp.shape[0] - g0), q0, par, bpos, bquat, jadr, jnum, jtype, jqadr,
                               jpos, jaxis, ps[g], np.int64(scratch.ctypes.data))


@pytest.mark.parametrize("scene", ["kinematics_mjcf", "anchors_at_origin", "no_hinge", "no_joint"] + SCENES)
def test_lane_kinematics_equal_world_kinematics_bit_for_bit(scene):
    # The fused batch computes the poses lanes at a time (`_kinematics_lanes`, into the lanes'
    # (L, 12, LANES) block) and kinematics_batch world by world (`_kinematics_world`): the same
    # operations in the same order, so the same bits, over full and partial groups of lanes.
    if scene in ("kinematics_mjcf", "anchors_at_origin"):
        model = _kin_model(scene)
    elif scene == "no_hinge":  # slide and ball joints only
        model = mujoco.MjModel.from_xml_string(KIN.replace('type="hinge" axis="0 1 1"', 'type="slide" axis="0 1 1"'))
    elif scene == "no_joint":  # static and mocap bodies: no joint at all
        model = mujoco.MjModel.from_xml_string(KIN.replace("<freejoint/>", "").replace(
            '<joint type="hinge" axis="0 1 1" pos=".05 0 0"/>', "").replace('<joint type="slide" axis="1 0 0"/>', "")
            .replace('<joint type="ball" pos="0 0 .1"/>', ""))
        assert model.njnt == 0
    else:
        model = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
    qpos = _random_qpos(model, 2 * LANES + 3, np.random.default_rng(17))
    hinges = model.jnt_qposadr[model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE]
    if len(hinges):  # one lane's half angle past _quat.SINCOS_MAX: libm there, in both
        qpos[LANES + 2, hinges[0]] = 3.5e6
    pos, rot = cm.kinematics_batch(model, qpos)
    groups = -(-len(qpos) // LANES)
    ps = np.empty((groups, model.nbody, 12, LANES))
    _lane_poses(qpos, cm.kinematic_tree(model).arrays, ps, np.empty(_kin.lanes_scratch_size(model.nbody, model.njnt)))
    for w in range(len(qpos)):
        g, lane = divmod(w, LANES)
        assert np.array_equal(ps[g, :, :3, lane], pos[w]) and np.array_equal(ps[g, :, 3:, lane], rot[w].reshape(-1, 9))
    # lanes past the last world repeat its group's first
    g, last = divmod(len(qpos) - 1, LANES)
    assert np.array_equal(ps[g, :, :3, last + 1], pos[g * LANES])
    assert np.array_equal(ps[g, :, 3:, last + 1], rot[g * LANES].reshape(-1, 9))


@numba.njit  # not cached: see _lane_poses
def _shortcuts(q, lq, out):
    # Row i: `_quat._turn` and `_rotate_about` about a zero anchor, then the product by the
    # identity quaternion and the quaternion itself (the kinematics' two shortcuts and what they
    # replace), each frame at position (0.3, -0.2, 0.1).
    for i in range(q.shape[0]):
        c0, c1, c2, c3 = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        l0, l1, l2, l3 = lq[i, 0], lq[i, 1], lq[i, 2], lq[i, 3]
        t = _quat._turn(0.3, -0.2, 0.1, c0, c1, c2, c3, l0, l1, l2, l3)
        r = _quat._rotate_about(0.3, -0.2, 0.1, c0, c1, c2, c3, l0, l1, l2, l3, 0.0, 0.0, 0.0)
        u = _quat._qmul(c0, c1, c2, c3, 1.0, 0.0, 0.0, 0.0)
        m = _quat._qmat(c0, c1, c2, c3)
        for k in range(7):
            out[i, 0, k] = t[k]
            out[i, 1, k] = r[k]
        for k in range(4):
            out[i, 2, k] = u[k]
            out[i, 3, k] = q[i, k]
        for k in range(3):
            out[i, 2, 4 + k] = m[k]


def test_kinematics_shortcuts_give_the_general_steps_values():
    # A joint anchored at its body's origin turns the quaternion only (`_quat._turn`) and an
    # identity body quaternion is not multiplied in: the same values as the general steps (a
    # zero's sign aside) on random unit quaternions. With a NaN in the quaternion the shortcut's
    # position stays finite, but every entry of the rotation it makes is NaN, so the pose check
    # refuses the body all the same.
    rng = np.random.default_rng(23)
    q = rng.normal(size=(2000, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    lq = rng.normal(size=(2000, 4))
    lq /= np.linalg.norm(lq, axis=1)[:, None]
    q[:5] = [[1, 0, 0, 0], [0, 1, 0, 0], [-0.0, 0, 0, 1], [0.5, -0.5, 0.5, -0.5], [1, -0.0, 0, -0.0]]
    out = np.zeros((len(q), 4, 7))
    _shortcuts(q, lq, out)
    assert np.array_equal(out[:, 0], out[:, 1])  # == on floats: +0 and -0 are equal
    assert np.array_equal(out[:, 2, :4], out[:, 3, :4])
    q[:, 1] = np.nan
    _shortcuts(q, lq, out)
    assert np.all(np.isfinite(out[:, 0, :3])) and np.all(np.isnan(out[:, 1, :3]))
    assert np.all(np.isnan(out[:, 0, 3:])) and np.all(np.isnan(out[:, 2, 4:]))


@numba.njit  # not cached: see _lane_poses
def _sincos_all(x, out):
    for i in range(x.size):
        out[i, 0], out[i, 1] = _quat._sincos(x[i])


def test_kinematics_sincos_within_two_ulps_of_libm():
    # The hinges' half angles go through _quat._sincos (vectorisable, unlike libm): within 1 ulp of
    # libm's sin and cos (math.sin, math.cos: numpy's may be another implementation) up to
    # |x| = 100, 2 ulp up to SINCOS_MAX; libm itself beyond, and for NaN and inf. Quadrant
    # boundaries (multiples of pi/4 and their neighbours) and signed zeros included.
    rng = np.random.default_rng(3)
    for scale, ulps in ((1.0, 1), (4.0, 1), (100.0, 1), (_quat.SINCOS_MAX, 2)):
        x = np.concatenate([rng.uniform(-scale, scale, 50_000), np.pi / 4 * np.arange(-9, 10),
                            np.nextafter(np.pi / 4 * np.arange(-9, 10, 2), np.inf), [0.0, -0.0]])
        got = np.empty((x.size, 2))
        _sincos_all(x, got)
        want = np.array([(math.sin(v), math.cos(v)) for v in x])
        assert np.all(np.abs(got - want) <= ulps * np.spacing(np.abs(want))), scale
        assert np.array_equal(np.signbit(got[want == 0]), np.signbit(want[want == 0]))  # sin(-0) = -0
    x = np.array([np.nan, np.inf, -np.inf, 2e6, -1e300])
    got = np.empty((x.size, 2))
    _sincos_all(x, got)
    assert np.all(np.isnan(got[:3])) and np.array_equal(got[3:], [[math.sin(v), math.cos(v)] for v in x[3:]])


def test_pairs_batch_calls_an_overridden_kinematics_batch():
    # A subclass's own kinematics is used on every path, the lanes' included.
    model = mujoco.MjModel.from_xml_string(CHAIN.format(fp="enable"))
    calls = []

    class Logged(cm.BroadPhase):
        def kinematics_batch(self, model, qpos):
            calls.append(len(qpos))
            return super().kinematics_batch(model, qpos)

    qpos = _random_qpos(model, 9, np.random.default_rng(12))
    got = Logged(model).pairs_batch(model, qpos)
    assert calls == [9] and np.array_equal(got, cm.BroadPhase(model).pairs_batch(model, qpos)) and len(got)


@pytest.mark.parametrize("scene", ["kinematics_mjcf", "anchors_at_origin"] + SCENES)
def test_kinematics_batch_matches_mj_kinematics(scene):
    if scene in ("kinematics_mjcf", "anchors_at_origin"):
        model = _kin_model(scene)
    else:
        model = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
    qpos = _random_qpos(model, 8, np.random.default_rng(7))
    pos, rot = cm.kinematics_batch(model, qpos)
    data = mujoco.MjData(model)
    for w in range(len(qpos)):
        data.qpos[:] = qpos[w]
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(pos[w], data.xpos, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rot[w], data.xmat.reshape(-1, 3, 3), rtol=0, atol=1e-12)


def test_pairs_follows_the_data_it_is_given():
    # Two MjData of one model, alternated: each call reads the poses of the data passed in.
    xml = CLUSTER.format(_free_sphere("a", "0 0 0") + _free_sphere("b", ".15 0 0"))
    model = mujoco.MjModel.from_xml_string(xml)
    near, far = mujoco.MjData(model), mujoco.MjData(model)
    far.qpos[7] += 5.0
    for d in (near, far):
        mujoco.mj_forward(model, d)
    bp = cm.BroadPhase(model)
    for _ in range(2):
        assert len(bp.pairs(near)) == 1 and len(bp.pairs(far)) == 0
    far.qpos[7] -= 5.0
    mujoco.mj_forward(model, far)
    assert len(bp.pairs(far)) == 1
    # other arrays bound to the core broad phase in between: the next call binds the data again
    far.qpos[7] += 5.0
    mujoco.mj_forward(model, far)
    bp.broadphase.bind(near.xpos.copy(), near.xmat.reshape(-1, 3, 3).copy())
    assert len(bp.pairs(far)) == 0


def test_unchanged_pairs_come_back_as_the_same_read_only_array():
    # pairs(data) on poses whose pairs are those of the last call: that call's array again.
    xml = CLUSTER.format(_free_sphere("a", "0 0 0") + _free_sphere("b", ".15 0 0"))
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bp = cm.BroadPhase(model)
    first = bp.pairs(data)
    assert len(first) == 1 and not first.flags.writeable
    mujoco.mj_step(model, data)  # the spheres move a little: the same pair
    assert bp.pairs(data) is first
    data.qpos[7] += 5.0
    mujoco.mj_forward(model, data)
    assert len(bp.pairs(data)) == 0
    data.qpos[7] -= 5.0
    mujoco.mj_forward(model, data)
    again = bp.pairs(data)  # the same pair as the last call that found any
    assert again is first and np.array_equal(first, [[0, 1]])


def test_unchanged_pairs_on_a_heightfield_model_come_back_as_the_same_array():
    # A model with a heightfield has its pairs without a collision function dropped after the
    # kernel (`_drop_null`): the filtered array too comes back while the pairs are unchanged.
    model = mujoco.MjModel.from_xml_string(TYPES)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bp = cm.BroadPhase(model)
    assert bp._no_function is not None  # the filtered path
    first = bp.pairs(data)
    assert len(first) >= 9 and not first.flags.writeable
    assert bp.pairs(data) is first
    mujoco.mj_step(model, data)  # everything at rest, or nearly: the same pairs
    assert bp.pairs(data) is first


def test_data_before_kinematics_is_reported():
    model = mujoco.MjModel.from_xml_string(CHAIN.format(fp="enable"))
    with pytest.raises(ValueError, match="mj_kinematics"):
        cm.BroadPhase(model).pairs(mujoco.MjData(model))


def test_bad_model_argument():
    with pytest.raises(ValueError, match="model"):
        cm.articulation("not a model")
    model = mujoco.MjModel.from_xml_string(CLUSTER.format(_free_sphere("a", "0 0 0") + _free_sphere("b", ".15 0 0")))
    bp = cm.BroadPhase(model)
    with pytest.raises(ValueError, match="data: expected a mujoco.MjData"):
        bp.pairs(None)
    with pytest.raises(ValueError, match="model: expected a mujoco.MjModel"):
        bp.pairs_batch(None, np.zeros((1, model.nq)))
    other = mujoco.MjModel.from_xml_string(CLUSTER.format(_free_sphere("a", "0 0 0")))
    with pytest.raises(ValueError, match="data: made for a model with 2 bodies"):
        bp.pairs(mujoco.MjData(other))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert len(bp.pairs(data)) == 1  # still usable


def test_copies_and_pickles_are_rebuilt():
    # Rebuilt from the model: the kernel's context holds addresses of the original's buffers.
    import copy
    import gc
    import pickle

    xml = CLUSTER.format(_free_sphere("a", "0 0 0") + _free_sphere("b", ".15 0 0") + _free_sphere("c", "2 0 0"))
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bp = cm.BroadPhase(model)
    want = bp.pairs(data)
    assert len(want) == 1
    copies = [copy.copy(bp), copy.deepcopy(bp), pickle.loads(pickle.dumps(bp))]
    del bp
    gc.collect()
    for c in copies:
        assert np.array_equal(c.pairs(data), want)
    walk = copy.copy(cm.BroadPhase(model, coherent=False))
    assert not walk.broadphase.coherent and np.array_equal(walk.pairs(data), want)


@pytest.mark.parametrize("objects", [40, 80])
def test_coherent_steps_equal_the_walk_in_a_simulation(objects):
    # The built-in scene (a figure falling onto a pile): MuJoCo's own steps. With 80 objects (more
    # than 64 positions) the kept body-pair list is reused in most of them, and the pairs are those
    # of a broad phase that walks the tree every step; with 40 no list is kept and both take the
    # static masks (the same code: their pairs are checked against MuJoCo's contacts in
    # test_scene_recall_is_complete and against the twin in test_broadphase's mask tests).
    model = cm.default_scene(seed=3, objects=objects)
    data = mujoco.MjData(model)
    coh, walk = cm.BroadPhase(model), cm.BroadPhase(model, coherent=False)
    assert (coh.broadphase.position_count > 64) == (objects == 80)
    rng = np.random.default_rng(0)
    reused = total = 0
    for step in range(400):
        if step % 50 == 0 and model.nu:
            data.ctrl[:] = rng.uniform(-1, 1, model.nu)
        mujoco.mj_step(model, data)
        got = coh.pairs(data)
        reused += coh.stats["reused"]
        assert np.array_equal(got, walk.pairs(data)), step
        total += len(got)
    assert total > 400 * 5  # the pile and the figure touch
    assert reused > 200 if objects == 80 else reused == 0


# ----------------------------------------------------------------------------------- real scenes

@pytest.mark.skipif(not SCENES, reason=f"the test models are not present at {MODELS} "
                    "(the team's shared checkout); nothing to compare against")
@pytest.mark.parametrize("scene", SCENES)
def test_scene_recall_is_complete(scene, tmp_path):
    model = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
    result = cm.compare(model, steps=2000, seed=0, name=scene)
    assert result["missed"] == [], cm.format_report(result)
    assert result["recall"] == 1.0
    contacts = np.asarray(result["contact_pairs_per_step"])
    ours = np.asarray(result["candidates_per_step"])
    assert result["steps"] == 2000 and len(contacts) == len(ours) == 2000
    assert contacts.sum() > 0, f"{scene}: no contact in 2000 steps, the test would test nothing"
    assert np.all(ours >= contacts)
    assert len(result["mujoco_candidates_per_step"]) == 2000
    # MuJoCo's candidates come from a second run; it must have simulated the same states.
    assert result["mujoco_count_replayed"] is True
    mj = np.asarray(result["mujoco_candidates_per_step"])
    assert np.all(mj[contacts > 0] > 0), "MuJoCo counted no candidate on a step with contacts"
    assert result["time_ours_us"] > 0 and result["time_mujoco_broad_us"] > 0
    # The JSON round trip keeps every figure.
    path = tmp_path / "r.json"
    path.write_text(json.dumps(result))
    back = json.loads(path.read_text())
    for key in ("steps", "recall", "missed", "contact_pairs_per_step", "candidates_per_step",
                "mujoco_candidates_per_step", "time_ours_us", "time_mujoco_broad_us"):
        assert back[key] == result[key]


@pytest.mark.skipif(not SCENES, reason=f"the test models are not present at {MODELS} "
                    "(the team's shared checkout); nothing to compare against")
@pytest.mark.parametrize("scene", SCENES)
def test_scene_batch_equals_single_worlds(scene):
    # Real models through pairs_batch: the small ones run in SIMD lanes, the big ones (22
    # humanoids) world by world; either way each world's rows are the single-world answer.
    model = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
    bp = cm.BroadPhase(model)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(6)
    lo, hi = cm._control_range(model)
    qpos, count = [], []
    for _ in range(300):
        data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data)
        qpos.append(data.qpos.copy())
        count.append(len(bp.pairs(data)))
    # and random configurations of the hinge and slide joints (an arm that never meets itself
    # under random controls folds onto itself here)
    hinge = np.flatnonzero(np.isin(model.jnt_type, [mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE]))
    adr = model.jnt_qposadr[hinge]
    rlo = np.where(model.jnt_limited[hinge], model.jnt_range[hinge, 0], -np.pi)
    rhi = np.where(model.jnt_limited[hinge], model.jnt_range[hinge, 1], np.pi)
    for _ in range(300):
        data.qpos[:] = model.qpos0
        data.qpos[adr] = rng.uniform(rlo, rhi)
        mujoco.mj_kinematics(model, data)
        qpos.append(data.qpos.copy())
        count.append(len(bp.pairs(data)))
    # 11 worlds (a full group of lanes and a partial one): the states with the most pairs
    qpos = np.array(qpos)[np.sort(np.argsort(count, kind="stable")[-11:])]
    assert _batch_equals_single_worlds(bp, model, qpos) > 0


@pytest.mark.skipif(not (MODELS / "humanoid" / "scene.xml").is_file(),
                    reason=f"the humanoid test model is not present under {MODELS}")
@pytest.mark.parametrize("variant", ["margin_gap", "override", "filterparent_off"])
def test_humanoid_variants_recall(variant):
    # The same real scene with the rules switched: margins and gaps on every geom, the global
    # margin override, the parent filter off. Contacts must still all be among our candidates.
    model = mujoco.MjModel.from_xml_path(str(MODELS / "humanoid" / "scene.xml"))
    rng = np.random.default_rng(5)
    if variant == "margin_gap":
        model.geom_margin[:] = rng.uniform(0.0, 0.02, size=model.ngeom)
        model.geom_gap[:] = rng.uniform(0.0, 0.01, size=model.ngeom)
    elif variant == "override":
        model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_OVERRIDE
        model.opt.o_margin = 0.03
    else:
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
    result = cm.compare(model, steps=1000, seed=1, name=variant)
    assert result["missed"] == [], cm.format_report(result)
    contacts = np.asarray(result["contact_pairs_per_step"])
    assert contacts.sum() > 0
    assert np.all(np.asarray(result["candidates_per_step"]) >= contacts)


FLEX_XML = """
<mujoco>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <body pos="0 0 0.3"><freejoint/><geom type="box" size="0.1 0.1 0.1"/></body>
    <body pos="0.3 0 0.3"><freejoint/><geom type="sphere" size="0.1"/></body>
    <flexcomp name="cloth" type="grid" count="6 6 1" spacing="0.08 0.08 0.08" pos="0 0 0.7" radius="0.01" dim="2">
      <contact selfcollide="none"/>
      <edge equality="true"/>
    </flexcomp>
  </worldbody>
</mujoco>
"""


def test_flex_contacts_are_counted_apart_and_reported():
    # A cloth (flex) falls on a box and a ball resting on the floor. Flex contacts are not geom
    # pairs: they are left out of the recall, and the report says how many there were.
    model = mujoco.MjModel.from_xml_string(FLEX_XML)
    assert model.nflex == 1
    result = cm.compare(model, steps=400, seed=0, name="flex")
    assert result["missed"] == [] and result["recall"] == 1.0
    assert result["contact_pairs_total"] > 0  # box and ball on the floor
    assert result["flex_contacts_total"] > 0
    assert f"{result['flex_contacts_total']} MuJoCo contacts involving a flex were left out" in cm.format_report(result)


@pytest.mark.parametrize("field, row, geom, xml", [
    # geom 1 placed by its own geom_quat (sameframe NONE)
    ("geom_quat", 1, 1, '<body><freejoint/><geom type="box" size=".1 .2 .3"/>'
                        '<geom type="capsule" size=".05 .2" pos=".3 0 0" euler="0 1 0"/></body>'),
    # geom 0 on its body's inertial frame (sameframe INERTIA): placed by body 1's body_iquat
    ("body_iquat", 1, 0, '<body><freejoint/><geom type="box" size=".1 .2 .3" euler="0 .5 0"/></body>'
                         '<body pos="1 0 0"><freejoint/><geom type="box" size=".1 .2 .3"/></body>'),
])
def test_a_quaternion_not_of_unit_norm_is_named_as_the_model_holds_it(field, row, geom, xml):
    # A quaternion set at run time to four digits: MuJoCo uses it as it is (its geom_xmat 4e-5 off
    # a rotation). The Collider refused it naming its own internal argument "geom_rot" (helper-77,
    # 2026-12-02): it names the model's field, and builds once the quaternion is normalised. A
    # geom on its inertial frame was named geom_quat too: ``in`` compared the bindings' enum (on
    # the left, whose __eq__ answers False) with a numpy scalar (2026-12-02).
    model = mujoco.MjModel.from_xml_string(f"<mujoco><worldbody>{xml}</worldbody></mujoco>")
    same = mujoco.mjtSameFrame
    want = same.mjSAMEFRAME_INERTIA if field == "body_iquat" else same.mjSAMEFRAME_NONE
    assert int(model.geom_sameframe[geom]) == int(want)
    quat = getattr(model, field)
    quat[row] = [0.7071, 0, 0.7071, 0]
    with pytest.raises(ValueError, match=rf"model.{field}: geom {geom}'s orientation is not a rotation"):
        cm.Collider(model)
    quat[row] /= np.linalg.norm(quat[row])
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert cm.Collider(model).geom_distance(data, 0, 1, 2.0)[0] < 2.0


def test_compare_measures_near_misses_from_the_contact_distance():
    # compare's counts of misses and extras "within ccd_tolerance" measured from distance 0, not
    # from the pair's contact distance (margin + gap): an extra contact 3e-8 inside a 2e-6 margin
    # was reported as beyond MuJoCo's tolerance (helper-77, 2026-12-02).
    from collide.mujoco import _compare

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom name="a" size=".1" margin=".01" gap=".002"/><body><freejoint/>'
        '<geom name="b" size=".1" pos=".5 0 0" margin=".01" gap=".002"/><geom name="c" size=".1" pos="0 .5 0"/>'
        '</body></worldbody><contact><pair geom1="a" geom2="c" margin=".05"/></contact></mujoco>')
    agreement = _compare._ContactAgreement(model)
    assert agreement._threshold(0, 1) == pytest.approx(0.024, abs=1e-15)  # both margins and gaps
    assert agreement._threshold(0, 2) == 0.05  # the explicit pair's own
    tol = agreement.tolerance
    assert tol > 0
    agreement.missed = [agreement._entry(0, (0, 1), 0.024 - tol / 2), agreement._entry(0, (0, 1), -1e-3)]
    agreement.extra = [agreement._entry(0, (0, 2), 0.05 - tol / 2), agreement._entry(0, (0, 2), 0.0)]
    summary = agreement.summary()
    assert summary["missed_near_touching"] == 1 and summary["extra_near_touching"] == 1
    assert summary["extra"][0]["threshold"] == 0.05


def test_compare_reports_height_field_pairs_as_left_out_not_missed():
    # A ball dropped on a height field: MuJoCo makes the contact, ours leaves the pair out
    # (`Contacts.skipped`). The report said "MISSED" (helper-77, 2026-12-02): it says "left out".
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><asset><hfield name="h" nrow="3" ncol="3" size=".5 .5 .05 .05" elevation="0 0 0 0 0 0 0 0 0"/>'
        '</asset><worldbody><geom name="hf" type="hfield" hfield="h"/><body pos="0 0 .2"><freejoint/>'
        '<geom name="ball" size=".1"/></body></worldbody></mujoco>')
    result = cm.compare(model, steps=200, seed=0, name="hfield")
    ct = result["contacts"]
    assert ct["skipped"] and ct["missed"] == []  # the ball rests on the height field
    assert {(e["name1"], e["name2"]) for e in ct["skipped"]} == {("hf", "ball")}
    text = cm.format_report(result)
    assert f"{len(ct['skipped'])} left out: a height field or SDF" in text and "MISSED" not in text


def test_world_bounds_contain_mujocos_own_geoms():
    # The adapter's world bounds (what the demo draws) against MuJoCo's own geom poses: every box
    # geom's corners and every sphere geom's extreme points lie in the geom's OBB, sphere and AABB.
    model = cm.default_scene(seed=2)
    data = mujoco.MjData(model)
    for _ in range(50):
        mujoco.mj_step(model, data)
    bp = cm.BroadPhase(model)
    wb = bp.world_bounds(data)
    assert wb.obb_center.shape == (model.ngeom, 3)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    kinds = {int(mujoco.mjtGeom.mjGEOM_BOX): signs,
             int(mujoco.mjtGeom.mjGEOM_SPHERE): np.vstack([np.eye(3), -np.eye(3)])}
    checked = 0
    for g in range(model.ngeom):
        t = int(model.geom_type[g])
        if t not in kinds:
            continue
        size = model.geom_size[g] if t == mujoco.mjtGeom.mjGEOM_BOX else model.geom_size[g, 0]
        pts = data.geom_xpos[g] + (kinds[t] * size) @ data.geom_xmat[g].reshape(3, 3).T
        local = (pts - wb.obb_center[g]) @ wb.obb_rot[g]
        assert np.all(np.abs(local) <= wb.obb_half[g] + 1e-9)
        assert np.all(np.linalg.norm(pts - wb.sphere_center[g], axis=1) <= wb.sphere_radius[g] + 1e-9)
        assert np.all((pts >= wb.aabb_min[g] - 1e-9) & (pts <= wb.aabb_max[g] + 1e-9))
        checked += 1
    assert checked > 5
    bodies = bp.world_bounds(data, of="bodies")
    assert bodies.aabb_min.shape == (model.nbody, 3)
    with pytest.raises(ValueError, match="body poses are all zero"):
        bp.world_bounds(mujoco.MjData(model))
    fresh, col = mujoco.MjData(model), cm.Collider(model)  # never posed: each entry point says so
    for call in (lambda: col.contacts(fresh), lambda: col.pairs(fresh), lambda: col.geom_distance(fresh, 1, 2, 1.0)):
        with pytest.raises(ValueError, match="poses are all zero; run mujoco.mj_kinematics"):
            call()
    assert col.geom_distance(data, 1, 2, 10.0)[0] < 10.0  # then a posed one answers
    with pytest.raises(ValueError, match="inflate: expected True or False"):
        bp.world_bounds(mujoco.MjData(model), inflate="yes")  # the argument named, not the poses
    with pytest.raises(ValueError, match="of: expected 'geoms' or 'bodies'"):
        bp.world_bounds(data, of="links")
    with pytest.raises(ValueError, match="expected a mujoco.MjData"):
        bp.world_bounds(model)


def test_mujoco_timer_runs_on_a_native_clock():
    # A Python clock adds its own call to every interval MuJoCo times (0.2-0.4 us a broad phase):
    # on Linux the timer is a compiled C callback (found 2026-11-22: caching it had failed, and
    # the fallback to the Python clock was silent).
    import sys
    import time

    if not sys.platform.startswith("linux"):
        pytest.skip("the native clock is Linux's clock_gettime")
    assert cm.timer_clock() == "native"
    clock = cm._compare._CLOCK[0]
    a = clock()
    time.sleep(0.02)
    assert 15_000 < clock() - a < 2_000_000  # microseconds
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><geom type='plane' size='1 1 .1'/><body pos='0 0 .1'><freejoint/>"
        "<geom type='sphere' size='.1'/></body></worldbody></mujoco>")
    data = mujoco.MjData(model)
    with cm.mujoco_timer():
        for _ in range(20):
            mujoco.mj_step(model, data)
    timer = data.timer[cm._TIMER_BROAD]
    assert timer.number == 20 and 0 < timer.duration < 20 * 1000


def test_compare_counts_resets_and_keeps_the_timer_right(monkeypatch, tmp_path):
    # A motor of gear 1e12 makes the simulation unstable at every step: MuJoCo resets it inside
    # mj_step and restarts its timers, which gave negative broad-phase times and one reset
    # counted for many.
    xml = """<mujoco><worldbody><geom type="plane" size="5 5 .1"/>
      <body pos="0 0 0.5"><joint name="h" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/></body></worldbody>
      <actuator><motor joint="h" gear="1e12" ctrlrange="-1 1"/></actuator></mujoco>"""
    monkeypatch.chdir(tmp_path)  # MuJoCo logs its warnings to MUJOCO_LOG.TXT in the working folder
    result = cm.compare(mujoco.MjModel.from_xml_string(xml), steps=30, seed=0, hold=1)
    assert result["unstable_resets"] == 30
    assert min(result["time_mujoco_broad_us_per_step"]) > 0 and result["recall"] == 1.0
    calm = cm.compare(cm.default_scene(seed=1), steps=30, seed=0)
    assert calm["unstable_resets"] == 0 and min(calm["time_mujoco_broad_us_per_step"]) > 0


def test_bad_values_edited_into_a_model_are_named():
    # Review, 2026-11-22: a negative size said "radius: must be >= 0" without the geom; a NaN
    # ccd_tolerance blamed geom_margin.
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><freejoint/><geom name="ball" size=".1"/></body></worldbody></mujoco>')
    model.geom_size[0, 0] = -1.0
    with pytest.raises(ValueError, match=r"geom 0 \(ball\): radius: must be >= 0"):
        cm.articulation(model)
    model.geom_size[0, 0] = 0.1
    model.opt.ccd_tolerance = float("nan")
    with pytest.raises(ValueError, match="model.opt.ccd_tolerance: must be finite"):
        cm.articulation(model)
    model.opt.ccd_tolerance = 1e-6
    model.geom_gap[0] = float("inf")
    with pytest.raises(ValueError, match=r"model.geom_gap: non-finite value \(NaN or inf\) at index \(0,\)"):
        cm.articulation(model)

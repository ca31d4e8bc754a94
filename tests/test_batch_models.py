"""`pairs_batch(model, qpos)` against `pairs(data)` on generated MJCF models (issue 48).

Models are drawn at random with a fixed seed: free, hinged, slid and ball-jointed bodies, world
planes (one tilted) and world boxes, mocap bodies, ``<pair>`` elements with and without margins
(plane pairs among them), ``<exclude>``, contype/conaffinity, margins and gaps. Every world of
``pairs_batch`` must equal the single-world answer on the same qpos (after ``mj_kinematics``), on a
fresh instance, after a call that raised, after calls of other batch sizes, and through the
per-world batch kernel (`collide.BroadPhase.pairs_batch`) too. The test asserts that its models
produced pairs, explicit pairs among them, so it cannot pass by testing nothing.
"""

import mujoco
import numpy as np
import pytest

import collide.mujoco as cm
from _threads import in_threads


def _geom(rng, name, extra=""):
    kind = rng.choice(["sphere", "box", "capsule", "ellipsoid", "cylinder"])
    size = {"sphere": ".08", "box": ".07 .05 .09", "capsule": ".04 .08", "ellipsoid": ".06 .08 .05",
            "cylinder": ".05 .07"}[kind]
    filt = ""
    u = rng.uniform()
    if u < 0.15:
        filt = ' contype="0" conaffinity="0"'  # reachable only through a <pair>
    elif u < 0.3:
        filt = ' contype="2" conaffinity="2"'
    elif u < 0.4:
        filt = f' margin="{rng.uniform(0, .05):.3f}" gap="{rng.uniform(0, .02):.3f}"'
    return f'<geom name="{name}" type="{kind}" size="{size}"{filt}{extra}/>'


def random_model(seed: int, bodies: int = 8) -> mujoco.MjModel:
    """A random MJCF model (see the module docstring); geoms named g0, g1, ..."""
    rng = np.random.default_rng(seed)
    names = []

    def geom(extra=""):
        names.append(f"g{len(names)}")
        return _geom(rng, names[-1], extra)

    world = ['<geom name="floor" type="plane" size="3 3 .1"/>']
    if rng.uniform() < 0.5:
        world.append('<geom name="wall" type="plane" size="2 2 .1" pos=".9 0 0" zaxis="-1 0 .2"/>')
    for _ in range(rng.integers(0, 3)):
        p = rng.uniform(-.5, .5, 3)
        world.append(f'<geom name="w{len(world)}" type="box" size=".1 .1 .1" pos="{p[0]:.3f} {p[1]:.3f} .1"/>')
    body_xml = []
    for b in range(bodies):
        p = rng.uniform([-.5, -.5, .05], [.5, .5, .6])
        kind = rng.choice(["free", "chain", "mocap", "ball_slide"], p=[.45, .3, .1, .15])
        head = f'<body name="b{b}" pos="{p[0]:.3f} {p[1]:.3f} {p[2]:.3f}"'
        if kind == "free":
            body_xml.append(f'{head}><freejoint/>{geom()}{geom() if rng.uniform() < .3 else ""}</body>')
        elif kind == "mocap":
            body_xml.append(f'{head} mocap="true">{geom()}</body>')
        elif kind == "ball_slide":
            body_xml.append(f'{head}><joint type="slide" axis="0 0 1"/><joint type="ball"/>{geom()}</body>')
        else:
            inner = ""
            for k in reversed(range(int(rng.integers(1, 4)))):
                axis = f"0 {rng.uniform(.2, 1):.2f} 1"
                inner = f'<body name="b{b}_{k}" pos=".12 0 0"><joint type="hinge" axis="{axis}"/>{geom()}{inner}</body>'
            body_xml.append(f'{head}><joint type="hinge" axis="0 0 1"/>{geom()}{inner}</body>')
    contact = []
    everything = names + [w.split('"')[1] for w in world]
    for _ in range(rng.integers(1, 4)):
        a, b = rng.choice(everything, 2, replace=False)
        if a in ("floor", "wall") and b in ("floor", "wall"):
            continue
        margin = f' margin="{rng.uniform(0, .1):.3f}"' if rng.uniform() < .5 else ""
        contact.append(f'<pair geom1="{a}" geom2="{b}"{margin}/>')
    if rng.uniform() < 0.6 and bodies > 1:
        a, b = rng.choice(bodies, 2, replace=False)
        contact.append(f'<exclude body1="b{a}" body2="b{b}"/>')
    xml = (f'<mujoco><worldbody>{"".join(world)}{"".join(body_xml)}</worldbody>'
           f'<contact>{"".join(contact)}</contact></mujoco>')
    return mujoco.MjModel.from_xml_string(xml)


def random_qpos(model, worlds, rng):
    """Configurations near qpos0: free bodies moved within 0.4 m, every joint turned at random."""
    q = np.tile(model.qpos0, (worlds, 1))
    for j in range(model.njnt):
        a, t = model.jnt_qposadr[j], model.jnt_type[j]
        if t == mujoco.mjtJoint.mjJNT_FREE:
            q[:, a:a + 3] += rng.uniform(-.4, .4, size=(worlds, 3))
            q[:, a + 3:a + 7] = rng.normal(size=(worlds, 4))
        elif t == mujoco.mjtJoint.mjJNT_BALL:
            q[:, a:a + 4] = rng.normal(size=(worlds, 4))
        elif t == mujoco.mjtJoint.mjJNT_SLIDE:
            q[:, a] += rng.uniform(-.3, .3, size=worlds)
        else:
            q[:, a] += rng.uniform(-np.pi, np.pi, size=worlds)
    return q


def single_worlds(bp, model, qpos):
    """Rows ``(world, g1, g2)`` of ``pairs(data)`` world by world, after ``mj_kinematics``."""
    data = mujoco.MjData(model)
    rows = []
    for w in range(len(qpos)):
        data.qpos[:] = qpos[w]
        mujoco.mj_kinematics(model, data)
        rows.extend((w, int(a), int(b)) for a, b in bp.pairs(data))
    return np.array(rows, np.int32).reshape(-1, 3)


def _explicit_rows(model, rows):
    explicit = {tuple(sorted(p)) for p in zip(model.pair_geom1, model.pair_geom2)}
    return sum(tuple(r[1:]) in explicit for r in rows.tolist())


SEEDS = range(24)


@pytest.mark.parametrize("seed", SEEDS)
def test_random_models_batch_equals_single_worlds(seed):
    model = random_model(seed)
    rng = np.random.default_rng(100 + seed)
    qpos = random_qpos(model, 19, rng)  # two full groups of lanes and a partial one
    want = single_worlds(cm.BroadPhase(model), model, qpos)
    bp = cm.BroadPhase(model)
    np.testing.assert_array_equal(bp.pairs_batch(model, qpos), want)
    # after a call that raised (a NaN in the first world of a full group)
    bad = qpos[:8].copy()
    bad[0, 2] = np.nan
    with pytest.raises(ValueError, match="qpos"):
        bp.pairs_batch(model, bad)
    np.testing.assert_array_equal(bp.pairs_batch(model, qpos), want)
    # after calls of other batch sizes, each one equal to its part of the answer
    for n in (1, 9, 3, 19):
        part = want[want[:, 0] < n]
        np.testing.assert_array_equal(bp.pairs_batch(model, qpos[:n]), part)
    # the per-world batch kernel on our kinematics' poses
    np.testing.assert_array_equal(bp.broadphase.pairs_batch(*cm.kinematics_batch(model, qpos)), want)
    _totals[seed] = (len(want), _explicit_rows(model, want))


_totals = {}


def test_random_models_had_hits():
    # Runs after the parametrized cases (file order): the scenes produced pairs, explicit ones too.
    if len(_totals) < len(SEEDS):
        pytest.skip("the random-model cases did not all run in this session")
    pairs = sum(t[0] for t in _totals.values())
    explicit = sum(t[1] for t in _totals.values())
    assert pairs > 200 and explicit > 10, (pairs, explicit)


def test_many_bodies_take_the_per_world_kernel_and_agree():
    # 100 free spheres: more static body pairs than the lanes take (`lanes.MAX_BODY_PAIRS`), so
    # pairs_batch runs world by world; with a <pair> to the floor and an excluded pair.
    model = random_model(7, bodies=100)
    assert cm.BroadPhase(model).broadphase.batch_path == "worlds"
    rng = np.random.default_rng(5)
    qpos = random_qpos(model, 5, rng)
    want = single_worlds(cm.BroadPhase(model), model, qpos)
    assert len(want) > 0
    bp = cm.BroadPhase(model)
    np.testing.assert_array_equal(bp.pairs_batch(model, qpos), want)


# ------------------------------------------------------------------------- the cases

FORTY = ("""<mujoco><worldbody><geom name="floor" type="plane" size="5 5 .1"/>
  <body name="A" pos="0 0 .3"><freejoint/><geom name="ga" type="box" size=".1 .1 .1"/></body>
  <body name="C" pos="-.05 0 .9"><freejoint/><geom name="gc" type="capsule" size=".05 .1"/></body>
  """ + "".join(f'<body pos="{i} 2 1"><freejoint/><geom type="sphere" size=".1"/></body>' for i in range(40))
         + """</worldbody><contact><pair geom1="gc" geom2="floor"/></contact></mujoco>""")


def _ab_model(pair):
    return mujoco.MjModel.from_xml_string(f"""<mujoco><worldbody><geom name="floor" type="plane" size="5 5 .1"/>
      <body name="A" pos="0 0 .3"><freejoint/><geom name="ga" type="box" size=".1 .1 .1"/></body>
      <body name="B" pos="2 0 .3"><freejoint/><geom name="gb" type="sphere" size=".1" contype="0" conaffinity="0"/>
      </body></worldbody><contact>{pair}</contact></mujoco>""")


def _forward(model):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return data


def test_explicit_plane_pair_in_a_batch_does_not_crash():
    # Was a segmentation fault: the explicit pairs' stage read a group pose buffer that the call
    # computing the poses in the lanes never wrote.
    model = mujoco.MjModel.from_xml_string(FORTY)
    data = _forward(model)
    qpos = np.tile(data.qpos, (4, 1))
    assert len(cm.BroadPhase(model).pairs_batch(model, qpos)) == 0
    qpos[:, 7 + 2] = 0.08  # C's capsule (free joint 2) down onto the floor in every world
    got = cm.BroadPhase(model).pairs_batch(model, qpos)
    np.testing.assert_array_equal(got, single_worlds(cm.BroadPhase(model), model, qpos))
    assert {(w, 0, 2) for w in range(4)} <= {tuple(r) for r in got.tolist()}  # gc-floor in each


def test_explicit_pair_found_after_a_call_that_raised():
    model = _ab_model('<pair geom1="gb" geom2="ga"/>')
    bp = cm.BroadPhase(model)
    data = _forward(model)
    touch = data.qpos.copy()
    touch[7:10] = [0.15, 0, 0.3]  # B's sphere overlaps A's box
    assert bp.pairs_batch(model, touch[None]).tolist() == [[0, 1, 2]]
    bad = np.tile(data.qpos, (8, 1))
    bad[0, 2] = np.nan
    with pytest.raises(ValueError, match=r"qpos: non-finite value .* index \(0, 2\)"):
        bp.pairs_batch(model, bad)
    assert bp.pairs_batch(model, touch[None]).tolist() == [[0, 1, 2]]


def test_far_explicit_pairs_are_not_reported():
    for pair in ('<pair geom1="gb" geom2="ga"/>', '<pair geom1="gb" geom2="floor"/>'):
        model = _ab_model(pair)
        data = _forward(model)
        far = np.tile(data.qpos, (4, 1))
        far[:, 9] = 2.0  # B 2 m above the floor, 2 m from A
        bp = cm.BroadPhase(model)
        assert bp.pairs_batch(model, far).shape == (0, 3), pair


def test_two_threads_share_one_broad_phase():
    # One instance from two threads, batch sizes varying: every answer right, no hang.
    model = random_model(3)
    rng = np.random.default_rng(11)
    qs = [random_qpos(model, int(n), rng) for n in rng.integers(1, 40, size=12)]
    want = [single_worlds(cm.BroadPhase(model), model, q) for q in qs]
    assert sum(len(w) for w in want) > 0
    bp = cm.BroadPhase(model)
    data = [mujoco.MjData(model) for _ in range(2)]

    def run(t):
        errors = []
        for r in range(20):
            i = (r + 5 * t) % len(qs)
            if not np.array_equal(bp.pairs_batch(model, qs[i]), want[i]):
                errors.append(("batch", t, r))
            d = data[t]
            d.qpos[:] = qs[i][0]
            mujoco.mj_kinematics(model, d)
            if not np.array_equal(bp.pairs(d), want[i][want[i][:, 0] == 0, 1:]):
                errors.append(("single", t, r))
        return errors

    errors = sum(in_threads(run, 2, timeout=300), [])
    assert not errors, errors[:5]


@pytest.mark.parametrize("kind", ["box", "capsule", "mesh"])
def test_large_margins_keep_every_mujoco_contact(kind):
    # MuJoCo's box-box collider makes contacts up to the margin along its separating axes, which
    # may be farther apart than the margin (0.536 apart, margin 0.5: a contact at dist 0.467); a
    # box's margin counts sqrt(3) times in our bounds (`collide.mujoco._model._box_factor`).
    other = {"box": 'type="box" size=".1 .07 .12"', "capsule": 'type="capsule" size=".05 .1"',
             "mesh": 'type="mesh" mesh="m"'}[kind]
    model = mujoco.MjModel.from_xml_string(f"""<mujoco><asset>
      <mesh name="m" vertex="0 0 0  .2 0 0  0 .15 0  0 0 .1  .1 .1 .1"/></asset>
      <option gravity="0 0 0"/><worldbody>
      <body><freejoint/><geom name="a" {other}/></body>
      <body><freejoint/><geom name="b" type="box" size=".0465 .077 .1156" margin=".5"/></body>
      </worldbody></mujoco>""")
    data = mujoco.MjData(model)
    bp = cm.BroadPhase(model)
    rng = np.random.default_rng(1)
    contacts = 0
    qs = []
    for _ in range(1500):
        q = np.zeros(14)
        q[3:7] = rng.normal(size=4)
        u = rng.normal(size=3)
        q[7:10] = u / np.linalg.norm(u) * rng.uniform(.3, .9)
        q[10:14] = rng.normal(size=4)
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        if data.ncon:
            contacts += 1
            qs.append(q)
            assert bp.pairs(data).tolist() == [[0, 1]], q.tolist()
    assert contacts > 200
    got = bp.pairs_batch(model, np.array(qs))
    assert len(got) == len(qs)


def test_box_box_contact_beyond_the_margin_is_a_candidate():
    # The adversarial review's case: MuJoCo's box-box contact at dist 0.467 (margin 0.5) between
    # boxes 0.536 apart, missed while a box's margin counted once.
    model = mujoco.MjModel.from_xml_string("""<mujoco><option gravity="0 0 0"/><worldbody>
      <body><freejoint/><geom name="a" type="box" size=".1163 .06995 .1085"/></body>
      <body><freejoint/><geom name="b" type="box" size=".0465 .07714 .1156" margin=".5"/>
        <geom name="c" type="sphere" size=".05" pos="0 0 .5" contype="2" conaffinity="2"/></body>
      </worldbody></mujoco>""")
    data = mujoco.MjData(model)
    data.qpos[:] = [-0.09841431725372346, -0.34682515893257604, 0.4843929762194805, 0.9525042289516391,
                    -0.19462775322404907, -0.22719040527611578, -0.056923204887606424, -0.3410626978929295,
                    0.39994245052926247, 0.44397810031146, 0.7238608522091402, 0.34612956672524203,
                    -0.5948488039961971, -0.04873079172296647]
    mujoco.mj_forward(model, data)
    assert [(c.geom1, c.geom2) for c in data.contact[:data.ncon]] == [(0, 1)]
    assert mujoco.mj_geomDistance(model, data, 0, 1, 10.0, None) > 0.5  # farther than the margin
    assert cm.BroadPhase(model).pairs(data).tolist() == [[0, 1]]
    assert cm.BroadPhase(model).pairs_batch(model, data.qpos[None]).tolist() == [[0, 0, 1]]

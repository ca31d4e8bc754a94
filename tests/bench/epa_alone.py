"""EPA alone against GJK alone on penetrating cube pairs, in compiled loops (a developer's tool).

    python tests/bench/epa_alone.py OUT.npy

200 random pairs of unit cubes (8-vertex clouds, cube_3x3x3's meshes' kind), the second's centre
0.6-1.0 from the first's, random rotations (seed 1): GJK's final simplex is taken once per pair,
then `collide._kernels.epa.epa` and `collide._kernels.gjk.gjk_within` are each timed over 300
calls (min of 5); printed: the means over the pairs per call and EPA's mean iteration count;
EPA's result rows go to OUT.npy (to compare two trees bit for bit with ``cmp``). Run with a
copy of the package first on PYTHONPATH to time that copy.
"""
import sys, time, numpy as np
from numba import njit
from collide._kernels.gjk import gjk_within
from collide._kernels.epa import epa
from scipy.spatial.transform import Rotation
rng = np.random.default_rng(1)
cube = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * 0.5
prm = np.zeros(4); e32 = np.zeros(1, np.int32)
M = 200
@njit
def g(sa, sb, W, WA, WB, lam, v, dirn, pa, pb, hints):
    return gjk_within(sa, sb, np.zeros(3), hints, 1e-10, 1.0, 128, W, WA, WB, lam, v, dirn, pa, pb)
@njit
def e(sa, sb, W, WA, WB, n, hints, lower, K, res):
    it = 0
    for _ in range(K):
        h = hints.copy()
        st, s, it = epa(sa, sb, W, WA, WB, n, h, 1e-10, 128, lower, res)
    return it
@njit
def gg(sa, sb, W, WA, WB, lam, v, dirn, pa, pb, hints, K):
    for _ in range(K):
        h = hints.copy()
        gjk_within(sa, sb, np.zeros(3), h, 1e-10, 1.0, 128, W, WA, WB, lam, v, dirn, pa, pb)
tg = te = 0.0; its = []; R = []
K = 300
for i in range(M):
    ra = Rotation.random(random_state=rng.integers(1 << 30)).as_matrix()
    rb = Rotation.random(random_state=rng.integers(1 << 30)).as_matrix()
    pa = np.zeros(3); pb = rng.normal(size=3); pb *= rng.uniform(0.6, 1.0) / np.linalg.norm(pb)
    sa = (0, prm, cube, e32, e32, ra, pa); sb = (0, prm, cube, e32, e32, rb, pb)
    W = np.zeros((4, 3)); WA = np.zeros((4, 3)); WB = np.zeros((4, 3)); lam = np.zeros(4); v = np.zeros(3); dirn = np.zeros(4)
    p1 = np.zeros(3); p2 = np.zeros(3); hints = np.array([-1, -1])
    st, n, lower, scale, it = g(sa, sb, W, WA, WB, lam, v, dirn, p1, p2, hints.copy())
    res = np.empty(13)
    e(sa, sb, W, WA, WB, n, hints, lower, 1, res); gg(sa, sb, W, WA, WB, lam, v, dirn, p1, p2, hints, 1)
    b1 = b2 = 1e9
    for r in range(5):
        t0 = time.perf_counter(); its.append(e(sa, sb, W, WA, WB, n, hints, lower, K, res)); b1 = min(b1, time.perf_counter() - t0)
        t0 = time.perf_counter(); gg(sa, sb, W, WA, WB, lam, v, dirn, p1, p2, hints, K); b2 = min(b2, time.perf_counter() - t0)
    te += b1 / K; tg += b2 / K; R.append(res.copy())
print("EPA us %.3f  GJK us %.3f  mean EPA iters %.1f" % (te / M * 1e6, tg / M * 1e6, np.mean(its)))
np.save(sys.argv[1], np.array(R))

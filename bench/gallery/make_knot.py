"""A trefoil-knot tube surface as a point cloud (172,973 points): points uniform along the curve
c(t) = (sin t + 2 sin 2t, cos t - 2 cos 2t, -sin 3t) and around the tube of radius 0.6.
usage: python3 make_knot.py OUT.csv"""
import sys, numpy as np
rng = np.random.default_rng(2009); n = 172973; r = 0.6
def c(t): return np.stack([np.sin(t) + 2*np.sin(2*t), np.cos(t) - 2*np.cos(2*t), -np.sin(3*t)], -1)
def dc(t): return np.stack([np.cos(t) + 4*np.cos(2*t), -np.sin(t) + 4*np.sin(2*t), -3*np.cos(3*t)], -1)
t = rng.uniform(0, 2*np.pi, 4*n); s = np.linalg.norm(dc(t), axis=1)
t = t[rng.uniform(0, s.max(), len(t)) < s][:n]
T = dc(t); T /= np.linalg.norm(T, axis=1, keepdims=True)
a = np.cross(T, [0.0, 0.0, 1.0]); a /= np.linalg.norm(a, axis=1, keepdims=True); b = np.cross(T, a)
phi = rng.uniform(0, 2*np.pi, n)
p = c(t) + r*(np.cos(phi)[:, None]*a + np.sin(phi)[:, None]*b)
np.savetxt(sys.argv[1], p, delimiter=',', fmt='%.5f', header='x,y,z', comments='')

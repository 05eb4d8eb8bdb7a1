"""N seeds uniform in [0.4, 4.1] x [0.4, 4.1] x [0.3, 2.2] (the room is [0, 4.5]^2 x [0, 2.5]),
generator seed 7. usage: python3 make_office_seeds.py OUT.csv N"""
import sys, numpy as np
r = np.random.default_rng(7); n = int(sys.argv[2])
p = np.c_[r.uniform(0.4, 4.1, n), r.uniform(0.4, 4.1, n), r.uniform(0.3, 2.2, n)]
np.savetxt(sys.argv[1], p, delimiter=',', fmt='%.4f')

#!/usr/bin/env python3
"""The scattered-data baseline of bench/fe_surfaces.cpp: SciPy's CloughTocher2DInterpolator (a C1 piecewise
cubic on the Delaunay triangulation of the points, interpolating them, as a height field z(x, y)).

Usage: clough_tocher_baseline.py POINTS GRID OUT
  POINTS: text, one point "x y z" per line; GRID: text, one "x y" per line; OUT: one z per line (nan outside
  the points' convex hull). Prints the seconds spent building the interpolant and evaluating it.
"""
import sys
import time

import numpy as np
from scipy.interpolate import CloughTocher2DInterpolator


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    points = np.loadtxt(sys.argv[1], ndmin=2)
    grid = np.loadtxt(sys.argv[2], ndmin=2)
    start = time.perf_counter()
    interpolant = CloughTocher2DInterpolator(points[:, :2], points[:, 2])
    z = interpolant(grid[:, 0], grid[:, 1])
    seconds = time.perf_counter() - start
    np.savetxt(sys.argv[3], z)
    print(f"{seconds:.6f}")


if __name__ == "__main__":
    main()

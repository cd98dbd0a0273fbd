#!/usr/bin/env bash
# Regenerates the recordings of this folder (deterministic: fixed seeds; recordings/README.md). Needs a build with
# the virtual scanner (Open3D) and, for kinect_pcl.s2mrec, ../shared/data/pcl_kinect_frames.
# Usage: recordings/make_recordings.sh [path/to/scan2model]   (default build/apps/scan2model)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
cli="${1:-$here/../build/apps/scan2model}"
cd "$here"
rm -f pot.s2mrec pot_laser.s2mrec block.s2mrec shell.s2mrec kinect_pcl.s2mrec
# The pot (the vase of synthetic case "vase") on a turntable, Kinect-class camera at QVGA 0.7 m away, 20 degrees
# above; turntable axis tilted 0.3 degrees and shifted 1.5 mm.
"$cli" record -q --compress --out pot.s2mrec --device \
  virtual:vase,steps=8,width=320,height=240,fx=262.5,fy=262.5,cx=159.5,cy=119.5,depth_units=mm,axis_tilt_deg=0.3,axis_offset_x=1.5,seed=1
# The same pot, laser-line scanner: 90 profiles of 200 rays per turn, 0.02 mm noise along the ray, axis tilted 0.1
# degrees.
"$cli" record -q --compress --out pot_laser.s2mrec --device \
  virtual:vase,sensor=laser,steps=90,points=200,elevation_deg=20,noise=0.02,axis_tilt_deg=0.1,seed=4
# The counterbored block (docs/examples/counterbored_block.part.json), Kinect-class camera at VGA 0.45 m away,
# 45 degrees above; axis tilted 0.3 degrees and shifted 1 mm.
"$cli" record -q --compress --out block.s2mrec --device \
  virtual:part,steps=8,depth_units=mm,distance=450,elevation_deg=45,axis_tilt_deg=0.3,axis_offset_x=1.0,seed=2
# The shell (synthetic case "spiral"), Kinect-class camera 0.4 m away, 6 stops at 30 degrees above and 6 below
# (the part turned over), half the default disparity noise.
"$cli" record -q --compress --out shell.s2mrec --device \
  virtual:spiral,steps=6,depth_units=mm,distance=400,elevation_deg=30:-30,disparity_noise=0.03,seed=3
# Three real Kinect depth frames (PCL's test data, BSD-3: README.md of this folder).
frames="$here/../../shared/data/pcl_kinect_frames"
if [ -d "$frames" ]; then
  "$cli" record -q --compress --out kinect_pcl.s2mrec "$frames"/frame_*_depth.tiff
else
  echo "skipping kinect_pcl.s2mrec: $frames not found" >&2
fi
ls -l "$here"/*.s2mrec

#!/usr/bin/env python3
"""OpenCV peer of the ball_tracker benchmark: classic CamShift on a TUM RGB-D folder.

Reads the folder written by
    cargo run -p ball_tracker --release --example bench_tracker -- --write-tum DIR
(rgb.txt, depth.txt, intrinsics.txt, ball.txt = "timestamp x y z", the ball centre in the camera
optical frame, m), runs per frame: cvtColor(RGB->HSV), calcBackProject of a hue-saturation
histogram, CamShift, and a 3D centre from depth with the Rust tracker's estimator (per
back-projected pixel in the window, the sphere-centre distance along the centroid ray; the
median). Prints per-frame time p50/p99 (us, image loading excluded) and mean
centre error (px and mm) as one JSON line.

The peer cannot detect: its window is initialised from the ground truth of the first frame
(the Rust tracker detects the ball by itself). Requires opencv-python-headless and numpy.

    python3 opencv_camshift.py DIR [--diameter-m 0.1] [--threads 1]
"""
import argparse
import json
import os
import sys
import time

import cv2
import numpy as np


def read_index(path):
    out = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            ts, name = line.split()[:2]
            out.append((float(ts), name))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("folder")
    ap.add_argument("--diameter-m", type=float, default=0.1)
    ap.add_argument("--threads", type=int, default=1,
                    help="OpenCV threads (1 matches the single-threaded Rust tracker)")
    args = ap.parse_args()
    cv2.setNumThreads(args.threads)
    d = args.folder
    rgb_idx = read_index(os.path.join(d, "rgb.txt"))
    depth_idx = read_index(os.path.join(d, "depth.txt"))
    fx, fy, cx, cy = 525.0, 525.0, 319.5, 239.5
    kpath = os.path.join(d, "intrinsics.txt")
    if os.path.exists(kpath):
        with open(kpath) as f:
            for line in f:
                if line.strip() and not line.startswith("#"):
                    fx, fy, cx, cy = map(float, line.split())
                    break
    truth = {}
    with open(os.path.join(d, "ball.txt")) as f:
        for line in f:
            if line.strip() and not line.startswith("#"):
                t, x, y, z = map(float, line.split())
                truth[round(t, 6)] = np.array([x, y, z])
    depth_by_ts = {round(t, 6): n for t, n in depth_idx}
    r = args.diameter_m / 2.0

    times_us, err_px, err_mm = [], [], []
    window = None
    hist = None
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 1)
    for ts, name in rgb_idx:
        key = round(ts, 6)
        bgr = cv2.imread(os.path.join(d, name), cv2.IMREAD_COLOR)
        depth = cv2.imread(os.path.join(d, depth_by_ts[key]), cv2.IMREAD_UNCHANGED)
        if bgr is None or depth is None:
            print(f"cannot read frame {ts}", file=sys.stderr)
            return 1
        t_c = truth[key]
        u_t = fx * t_c[0] / t_c[2] + cx
        v_t = fy * t_c[1] / t_c[2] + cy
        if window is None:
            # Initialise from ground truth: the ball's projected bounding square.
            rad = fx * r / t_c[2]
            window = (int(u_t - rad), int(v_t - rad), int(2 * rad), int(2 * rad))
            hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
            x, y, w, h = window
            roi = hsv[y:y + h, x:x + w]
            mask = cv2.inRange(roi, np.array((0.0, 60.0, 32.0)), np.array((180.0, 255.0, 255.0)))
            hist = cv2.calcHist([roi], [0, 1], mask, [30, 32], [0, 180, 0, 256])
            cv2.normalize(hist, hist, 0, 255, cv2.NORM_MINMAX)
        t0 = time.perf_counter_ns()
        hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
        prob = cv2.calcBackProject([hsv], [0, 1], hist, [0, 180, 0, 256], 1)
        rot, window = cv2.CamShift(prob, window, crit)
        (uc, vc), _, _ = rot
        x, y, w, h = window
        centre = None
        if w > 0 and h > 0:
            pw = prob[y:y + h, x:x + w]
            dw = depth[y:y + h, x:x + w]
            sel = (pw > 0) & (dw > 0)
            if np.count_nonzero(sel) >= 3:
                # Per ball pixel: the distance t along the centroid ray at which a sphere of
                # radius r through the pixel's surface point is centred; median of t.
                ray = np.array([(uc - cx) / fx, (vc - cy) / fy, 1.0])
                ray /= np.linalg.norm(ray)
                vs, us = np.nonzero(sel)
                z = dw[sel].astype(np.float64) / 5000.0
                px = np.stack([(us + x - cx) * z / fx, (vs + y - cy) * z / fy, z], axis=1)
                a = px @ ray
                perp2 = np.maximum((px * px).sum(axis=1) - a * a, 0.0)
                t = a + np.sqrt(np.maximum(r * r - perp2, 0.0))
                centre = ray * float(np.median(t))
        times_us.append((time.perf_counter_ns() - t0) / 1000.0)
        err_px.append(float(np.hypot(uc - u_t, vc - v_t)))
        if centre is not None:
            err_mm.append(float(np.linalg.norm(centre - t_c)) * 1000.0)

    times = np.array(times_us)
    res = {
        "impl": "opencv_camshift",
        "opencv": cv2.__version__,
        "threads": args.threads,
        "frames": len(times_us),
        "p50_us": round(float(np.percentile(times, 50)), 1),
        "p99_us": round(float(np.percentile(times, 99)), 1),
        "mean_err_px": round(float(np.mean(err_px)), 3),
        "mean_err_mm": round(float(np.mean(err_mm)), 3) if err_mm else None,
        "frames_with_3d": len(err_mm),
    }
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())

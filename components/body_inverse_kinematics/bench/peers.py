#!/usr/bin/env python3
"""Peer IK solvers on the same URDF and targets as `examples/bench_ik.rs`, and the comparison.

Usage: peers.py TARGETS.json OURS.json [--n-ikpy 500] [--n-rtb 10000]

- TARGETS.json: written by `bench_ik --targets-out` (URDF path, per case: root and tip links,
  joint names, start configuration, targets as [x, y, z, qx, qy, qz, qw] in the root frame).
- OURS.json: `bench_ik --results-out` (our success %, p50 and p99 in microseconds).

Each case's chain is cut out of the URDF (only the links and joints on the path root -> tip) so
that both peers see exactly the chain we solve. Peers:
- ikpy (`Chain.inverse_kinematics_frame`, scipy least squares): orientation_mode "all" for poses.
- roboticstoolbox-python's C++ `ETS.ik_LM` (Levenberg-Marquardt, "chan" damping, random restarts
  `slimit`, joint limits on): mask [1,1,1,0,0,0] for position targets.
Both start from the same configuration as ours; success is judged here with each peer's own FK:
position error <= tolerance_m, rotation error <= tolerance_rad (poses), within joint limits.
Times are wall-clock around the Python call (so they include the Python-call overhead, a few
microseconds).

Prints a table and, as the very last line, one JSON object with every figure and the speed-up
ratios (peer p50 / our p50, peer p99 / our p99).
"""

import argparse
import json
import math
import os
import sys
import tempfile
import time
import warnings
import xml.etree.ElementTree as ET

import numpy as np

warnings.filterwarnings("ignore")


def chain_urdf(urdf_path, root, tip, out_dir):
    """A URDF holding only the path root -> tip; returns its path."""
    tree = ET.parse(urdf_path)
    robot = tree.getroot()
    joints = {j.find("child").get("link"): j for j in robot.findall("joint")}
    path_joints, cur = [], tip
    while cur != root:
        j = joints[cur]
        path_joints.append(j)
        cur = j.find("parent").get("link")
    keep_links = {root} | {j.find("child").get("link") for j in path_joints}
    keep_joints = {j.get("name") for j in path_joints}
    for el in list(robot):
        if el.tag == "link" and el.get("name") not in keep_links:
            robot.remove(el)
        elif el.tag == "joint" and el.get("name") not in keep_joints:
            robot.remove(el)
        elif el.tag not in ("link", "joint"):
            robot.remove(el)
    path = os.path.join(out_dir, f"{root}__{tip}.urdf")
    tree.write(path)
    return path


def pose_matrix(row):
    x, y, z, qx, qy, qz, qw = row
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    qx, qy, qz, qw = qx / n, qy / n, qz / n, qw / n
    r = np.array(
        [
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
        ]
    )
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = [x, y, z]
    return t


def pose_ok(t_got, t_want, pose, tol_m, tol_rad):
    dp = np.linalg.norm(t_got[:3, 3] - t_want[:3, 3])
    if dp > tol_m:
        return False
    if not pose:
        return True
    r = t_want[:3, :3] @ t_got[:3, :3].T
    c = max(-1.0, min(1.0, (np.trace(r) - 1.0) / 2.0))
    return math.acos(c) <= tol_rad


def pct(xs, p):
    if not xs:
        return float("nan")
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p / 100.0 * (len(xs) - 1))))]


def run_ikpy(case, urdf, n, tol_m, tol_rad):
    from ikpy.chain import Chain

    chain = Chain.from_urdf_file(urdf, base_elements=[case["root"]])
    mask = [link.joint_type != "fixed" for link in chain.links]
    mask[0] = False
    chain = Chain.from_urdf_file(urdf, base_elements=[case["root"]], active_links_mask=mask)
    active = [i for i, m in enumerate(mask) if m]
    names = [chain.links[i].name for i in active]
    if names != case["joints"]:
        raise RuntimeError(f"ikpy chain joints {names} != {case['joints']}")
    bounds = [chain.links[i].bounds for i in active]
    q0 = np.zeros(len(chain.links))
    q0[active] = case["q_start"]
    times, ok = [], 0
    for row in case["targets_xyz_qxyzw"][:n]:
        t = pose_matrix(row)
        start = time.perf_counter()
        if case["pose"]:
            q = chain.inverse_kinematics_frame(t, initial_position=q0, orientation_mode="all")
        else:
            q = chain.inverse_kinematics(t[:3, 3], initial_position=q0)
        times.append((time.perf_counter() - start) * 1e6)
        within = all(lo - 1e-9 <= q[i] <= hi + 1e-9 for i, (lo, hi) in zip(active, bounds))
        if within and pose_ok(chain.forward_kinematics(q), t, case["pose"], tol_m, tol_rad):
            ok += 1
    return {"success_pct": 100.0 * ok / n, "p50_us": pct(times, 50), "p99_us": pct(times, 99), "n": n}


def run_rtb(case, urdf, n, tol_m, tol_rad):
    import roboticstoolbox as rtb
    from roboticstoolbox.models.URDF.URDFRobot import URDF_file

    elinks, name, *_ = URDF_file(urdf)
    robot = rtb.Robot(elinks, name=name)
    ets = robot.ets(start=case["root"], end=case["tip"])
    if ets.n != len(case["joints"]):
        raise RuntimeError(f"rtb chain has {ets.n} joints, expected {len(case['joints'])}")
    qlim = ets.qlim
    mask = np.array([1, 1, 1, 1, 1, 1.0] if case["pose"] else [1, 1, 1, 0, 0, 0.0])
    q0 = np.array(case["q_start"], dtype=float)
    # rtb stops when E = 0.5 e'e < tol: the loosest tol that still guarantees |e| <= 1 mm / 0.01 rad.
    tol = 0.5 * min(tol_m, tol_rad) ** 2
    times, ok = [], 0
    for row in case["targets_xyz_qxyzw"][:n]:
        t = pose_matrix(row)
        start = time.perf_counter()
        sol = ets.ik_LM(t, q0=q0, ilimit=30, slimit=100, tol=tol, mask=mask, joint_limits=True)
        times.append((time.perf_counter() - start) * 1e6)
        q = np.asarray(sol.q, dtype=float)
        within = bool(np.all(q >= qlim[0] - 1e-9) and np.all(q <= qlim[1] + 1e-9))
        if sol.success and within and pose_ok(np.asarray(ets.fkine(q).A), t, case["pose"], tol_m, tol_rad):
            ok += 1
    return {"success_pct": 100.0 * ok / n, "p50_us": pct(times, 50), "p99_us": pct(times, 99), "n": n}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("targets")
    ap.add_argument("ours")
    ap.add_argument("--n-ikpy", type=int, default=500)
    ap.add_argument("--n-rtb", type=int, default=10000)
    args = ap.parse_args()
    with open(args.targets) as f:
        doc = json.load(f)
    with open(args.ours) as f:
        ours = json.load(f)
    tol_m, tol_rad = doc["tolerance_m"], doc["tolerance_rad"]
    peers = {}
    notes = []
    tmp = tempfile.mkdtemp(prefix="ik_peers_")
    for peer, runner, n_peer in (("ikpy", run_ikpy, args.n_ikpy), ("rtb", run_rtb, args.n_rtb)):
        for case in doc["cases"]:
            urdf = chain_urdf(doc["urdf"], case["root"], case["tip"], tmp)
            n = min(n_peer, len(case["targets_xyz_qxyzw"]))
            try:
                peers[(peer, case["name"])] = runner(case, urdf, n, tol_m, tol_rad)
            except Exception as e:  # report, never fake figures
                notes.append(f"{peer} {case['name']}: unavailable ({type(e).__name__}: {e})")
            print(f"  {peer} {case['name']}: done", file=sys.stderr)

    print()
    print(f"IK on Loki ({os.path.basename(doc['urdf'])}), tolerance {tol_m} m / {tol_rad} rad, "
          f"same targets and start configuration for everyone")
    print(f"{'case':<22} {'solver':<12} {'n':>6} {'success%':>9} {'p50_us':>10} {'p99_us':>10}")
    summary = {}
    for case in doc["cases"]:
        name = case["name"]
        rows = [("robocog", ours.get(name))] + [(p, peers.get((p, name))) for p in ("ikpy", "rtb")]
        for solver, r in rows:
            if r is None:
                print(f"{name:<22} {solver:<12} {'-':>6} {'n/a':>9}")
                continue
            print(f"{name:<22} {solver:<12} {r['n']:>6} {r['success_pct']:>9.2f} "
                  f"{r['p50_us']:>10.1f} {r['p99_us']:>10.1f}")
            prefix = "" if solver == "robocog" else f"{solver}_"
            summary[f"{prefix}{name}_success_pct"] = round(r["success_pct"], 3)
            summary[f"{prefix}{name}_p50_us"] = round(r["p50_us"], 2)
            summary[f"{prefix}{name}_p99_us"] = round(r["p99_us"], 2)
        me = ours.get(name)
        for p in ("ikpy", "rtb"):
            r = peers.get((p, name))
            if me and r:
                summary[f"speedup_p50_vs_{p}_{name}"] = round(r["p50_us"] / me["p50_us"], 2)
                summary[f"speedup_p99_vs_{p}_{name}"] = round(r["p99_us"] / me["p99_us"], 2)
    for extra in ours:
        if extra not in {c["name"] for c in doc["cases"]}:
            r = ours[extra]
            print(f"{extra:<22} {'robocog':<12} {r['n']:>6} {r['success_pct']:>9.2f} "
                  f"{r['p50_us']:>10.1f} {r['p99_us']:>10.1f}   (self-collision check on)")
            summary[f"{extra}_success_pct"] = round(r["success_pct"], 3)
            summary[f"{extra}_p50_us"] = round(r["p50_us"], 2)
    n_ikpy = min(args.n_ikpy, len(doc["cases"][0]["targets_xyz_qxyzw"]))
    print(f"note: ikpy is slow (scipy), so it solves only the first {n_ikpy} targets of each case; "
          f"rtb solves the first {args.n_rtb}.")
    print("note: rtb = roboticstoolbox-python C++ ik_LM (ilimit 30, slimit 100 restarts, joint limits on, tol E < 0.5 * (1e-3)^2); "
          "peer times include the Python call overhead.")
    for n in notes:
        print("note:", n)
    summary["ikpy_targets_per_case"] = n_ikpy
    print(json.dumps(summary))


if __name__ == "__main__":
    main()

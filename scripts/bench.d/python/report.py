"""`scripts/bench python`: the tables and the last line (one JSON object) from the runs' outputs.

Usage: report.py FOLDER, where FOLDER holds one file per run, each ending with the JSON object of
its probe: py_py, py_rust, rust_py, rust_rust (bench_bus_machines probe), rust_bus (bench_bus),
zenoh_py, py_zenoh_py, zenoh_py_py.
"""

from __future__ import annotations

import json
import math
import os
import sys


def last_json(path: str) -> dict:
    with open(path) as f:
        lines = [l for l in f.read().splitlines() if l.strip()]
    if not lines:
        raise SystemExit(f"report: {path} is empty")
    return json.loads(lines[-1])


def main() -> None:
    folder = sys.argv[1]
    quick = "--quick" in sys.argv[2:]
    runs = {
        name: last_json(os.path.join(folder, f"{name}.json"))
        for name in [
            "py_py",
            "py_rust",
            "rust_py",
            "rust_rust",
            "rust_bus",
            "zenoh_py",
            "py_zenoh_py",
            "zenoh_py_py",
        ]
    }

    def python_end(r: dict) -> dict:
        """Figures of a Python probe (robocog or zenoh-python)."""
        return {
            "64b_p50_us": r.get("small_p50_us"),
            "64b_p99_us": r.get("small_p99_us"),
            "64b_msgs_per_s": r.get("small_msgs_per_s"),
            "64b_sent": r.get("small_sent"),
            "64b_received": r.get("small_received"),
            "frame_p50_us": r.get("frame_p50_us"),
            "frame_p99_us": r.get("frame_p99_us"),
            "frame_msgs_per_s": r.get("frame_msgs_per_s"),
            "frame_sent": r.get("frame_sent"),
            "frame_received": r.get("frame_received"),
            "frame_received_shm": r.get("frame_received_shm"),
        }

    def rust_probe(r: dict) -> dict:
        """Figures of the Rust probe (bench_bus_machines --role probe)."""
        return {
            "64b_p50_us": r.get("p50_us_64b"),
            "64b_p99_us": r.get("p99_us_64b"),
            "64b_msgs_per_s": r.get("throughput_msgs_per_s"),
            "64b_sent": r.get("throughput_sent"),
            "64b_received": r.get("throughput_received"),
        }

    bus = runs["rust_bus"]
    rr = rust_probe(runs["rust_rust"])
    # The frame reference: bench_bus, the echo re-publishing the frame from its borrowed view
    # (one copy, as the Python echo must re-publish), read in place at the probe.
    rr.update(
        {
            "frame_p50_us": bus.get("typed_rgbd_republish_p50_us"),
            "frame_p99_us": bus.get("typed_rgbd_republish_p99_us"),
        }
    )
    pairs = {
        "py_py": python_end(runs["py_py"]),
        "py_rust": python_end(runs["py_rust"]),
        "rust_py": rust_probe(runs["rust_py"]),
        "rust_rust": rr,
        "rust_rust_relay": {
            "frame_p50_us": bus.get("typed_rgbd_p50_us"),
            "frame_p99_us": bus.get("typed_rgbd_p99_us"),
        },
        "zenoh_py": python_end(runs["zenoh_py"]),
        "py_zenoh_py": python_end(runs["py_zenoh_py"]),
        "zenoh_py_py": python_end(runs["zenoh_py_py"]),
    }
    labels = {
        "py_py": "Python -> Python (robocog both ends)",
        "py_rust": "Python probe -> Rust echo",
        "rust_py": "Rust probe -> Python echo",
        "rust_rust": "Rust <-> Rust (reference; 64 B: two processes; frame: bench_bus, echo re-publishes)",
        "rust_rust_relay": "Rust <-> Rust, frame relayed as received (no copy at the echo)",
        "zenoh_py": "plain zenoh-python <-> plain zenoh-python (baseline)",
        "py_zenoh_py": "Python probe -> plain zenoh-python echo",
        "zenoh_py_py": "plain zenoh-python probe -> Python echo",
    }

    def ok(v) -> bool:
        return isinstance(v, (int, float)) and not math.isnan(v) and v > 0

    out: dict = {}
    for pair, f in pairs.items():
        for k, v in f.items():
            if v is not None:
                out[f"{pair}_{k}"] = v
    # Ratios against the Rust reference and the plain zenoh-python client.
    for pair, f in pairs.items():
        if pair in ("rust_rust_relay",):
            continue
        for ref_name in ("rust_rust", "zenoh_py"):
            if pair == ref_name:
                continue
            ref = pairs[ref_name]
            tag = "rust" if ref_name == "rust_rust" else "zenoh_py"
            for size in ("64b", "frame"):
                for m in ("p50", "p99"):
                    a, b = f.get(f"{size}_{m}_us"), ref.get(f"{size}_{m}_us")
                    if ok(a) and ok(b):
                        out[f"{pair}_{size}_{m}_ratio_vs_{tag}"] = a / b
                a, b = f.get(f"{size}_msgs_per_s"), ref.get(f"{size}_msgs_per_s")
                if ok(a) and ok(b):
                    out[f"{pair}_{size}_msgs_per_s_ratio_vs_{tag}"] = a / b

    # No copy of the pixels on the way to a Python callback: the probe's arrays borrow the sample
    # (own no data) and the sample is the publisher's shared memory.
    py = runs["py_py"]
    seen = py.get("frames_received", 0)
    owning = py.get("frames_arrays_owning_data", 0)
    in_shm = py.get("frames_in_shm", 0)
    out["frame_arrays_own_data"] = owning > 0
    out["frame_samples_in_shm_share"] = in_shm / seen if seen else 0.0
    out["frame_pixels_copied"] = bool(seen == 0 or owning > 0 or in_shm < seen)
    out["frame_bytes"] = py.get("frame_bytes")
    steps = [
        ("publish_bytes", "Publisher.publish of a frame whose pixels are `bytes`"),
        ("publish_numpy", "Publisher.publish of a frame whose pixels are NumPy arrays"),
        ("publish_received", "Publisher.publish of a received frame (memoryviews: an echo, a relay)"),
        ("encode", "robocog.encode of a frame (`bytes` pixels)"),
        ("views", "images.rgb + images.depth_mm of a received frame (NumPy views)"),
        ("read_all_bytes", "reading every byte of them once (NumPy, 8 bytes at a time)"),
        ("copy", "bytes() of a received frame's two images (one copy)"),
    ]
    for k, _ in steps:
        v = py.get(f"step_{k}_us")
        if v is not None:
            out[f"py_frame_step_{k}_us"] = v
    out["quick"] = quick

    r_frame = out.get("py_py_frame_p50_ratio_vs_rust")
    r_small = out.get("py_py_64b_p50_ratio_vs_rust")
    out["target_frame_within_1_5x_rust_met"] = bool(
        r_frame is not None and r_frame <= 1.5 and not out["frame_pixels_copied"]
    )
    out["target_64b_within_3x_rust_met"] = bool(r_small is not None and r_small <= 3.0)

    def fmt(v, digits=1) -> str:
        if not ok(v):
            return "n/a"
        return f"{v:,.{digits}f}"

    def ratio(pair: str, size: str, m: str, tag: str) -> str:
        v = out.get(f"{pair}_{size}_{m}_ratio_vs_{tag}")
        return f"{v:.2f}" if v is not None else "n/a"

    print()
    print(
        "Publish-to-callback latency, one way = round trip / 2 (ping on one topic, pong on "
        "another), all on loopback through one zenoh router (robocog router), every end a client."
    )
    print(
        "64 B: a Ping with 64 bytes of data (96 B of CDR); frame: an RgbdFrame 640x480, rgb8 + "
        f"16UC1 depth ({out['frame_bytes']:,} B of CDR), every byte of it read by the probe."
    )
    print()
    print(
        "| pairing (probe -> echo) | 64 B p50 µs | 64 B p99 µs | frame p50 µs | frame p99 µs "
        "| 64 B p50 / Rust | frame p50 / Rust | 64 B p50 / zenoh-py | frame p50 / zenoh-py |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for pair, f in pairs.items():
        print(
            f"| {labels[pair]} | {fmt(f.get('64b_p50_us'))} | {fmt(f.get('64b_p99_us'))} "
            f"| {fmt(f.get('frame_p50_us'))} | {fmt(f.get('frame_p99_us'))} "
            f"| {ratio(pair, '64b', 'p50', 'rust')} | {ratio(pair, 'frame', 'p50', 'rust')} "
            f"| {ratio(pair, '64b', 'p50', 'zenoh_py')} | {ratio(pair, 'frame', 'p50', 'zenoh_py')} |"
        )
    print()
    print(
        "Throughput one way: the probe publishes as fast as it can (Python: for "
        f"{1 if quick else 3} s; Rust: {50_000 if quick else 500_000:,} messages), the echo counts "
        "what its callback gets; messages/s = received / (last - first). Small messages are "
        "Counter64 (28 B of CDR, the smallest message; what the Rust echo counts)."
    )
    print()
    print(
        "| pairing (sender -> receiver) | small msgs/s | sent | received "
        "| frames/s | sent | received | in shared memory | small / Rust | small / zenoh-py | frames / zenoh-py |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for pair, f in pairs.items():
        if pair == "rust_rust_relay":
            continue
        print(
            f"| {labels[pair]} | {fmt(f.get('64b_msgs_per_s'), 0)} | {fmt(f.get('64b_sent'), 0)} "
            f"| {fmt(f.get('64b_received'), 0)} | {fmt(f.get('frame_msgs_per_s'), 0)} "
            f"| {fmt(f.get('frame_sent'), 0)} | {fmt(f.get('frame_received'), 0)} "
            f"| {fmt(f.get('frame_received_shm'), 0)} "
            f"| {ratio(pair, '64b', 'msgs_per_s', 'rust')} "
            f"| {ratio(pair, '64b', 'msgs_per_s', 'zenoh_py')} "
            f"| {ratio(pair, 'frame', 'msgs_per_s', 'zenoh_py')} |"
        )
    print()
    print(
        "n/a: no existing Rust program echoes or counts an RgbdFrame across processes "
        "(bench_bus_machines echoes Pings and counts Counter64, with shared memory off); the Rust "
        "frame reference is bench_bus (three sessions in one process, through its own router)."
    )
    print()
    print("| one frame in Python (robocog probe, alone, no subscriber) | median µs |")
    print("|---|---:|")
    for k, label in steps:
        print(f"| {label} | {fmt(out.get(f'py_frame_step_{k}_us'))} |")
    print()
    print(
        f"Frames at the Python probe's callback (py_py): {in_shm} of {seen} in shared memory, "
        f"arrays owning their data in {owning}: pixels copied on the way: "
        f"{'yes' if out['frame_pixels_copied'] else 'no'}."
    )

    def verdict(met: bool) -> str:
        return "met" if met else "NOT met"

    print(
        "targets: a frame reaches a Python callback within 1.5x the Rust latency with no copy "
        f"of its pixels ({verdict(out['target_frame_within_1_5x_rust_met'])}: "
        f"{r_frame if r_frame is None else round(r_frame, 2)}x), "
        f"64 B within 3x ({verdict(out['target_64b_within_3x_rust_met'])}: "
        f"{r_small if r_small is None else round(r_small, 2)}x)"
    )
    print(json.dumps(out, sort_keys=True))


if __name__ == "__main__":
    main()

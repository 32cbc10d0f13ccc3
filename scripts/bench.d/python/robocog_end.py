"""`scripts/bench python`: one end on the bus through the `robocog` Python package.

--role echo: sends every Ping of bench/ping back on bench/pong and every RgbdFrame of bench/frame
    back on bench/frame_back (publishing the received message again: the Python API has no relay),
    counts the Counter64 of bench/count and the frames of bench/frame_count (as NumPy views) and
    reports each count, as the Rust `bench_bus_machines --role echo` does. Prints `ready`, then
    runs until SIGTERM.
--role probe: ping-pong of 64 B Pings and of 640x480 RGB-D frames (one-way = round trip / 2), then
    Counter64 messages and frames one way for a few seconds, counted by the echo. Prints one JSON
    object.
--role templates: writes the CDR bytes the plain zenoh client sends (robocog.encode, so the same
    bytes as a robocog publisher's) into a folder, with the offsets it patches.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common as c  # noqa: E402

import robocog  # noqa: E402
from robocog import images, msg  # noqa: E402


def frame_message(seq: int = 0) -> msg.RgbdFrame:
    """A 640x480 RGB-D frame (rgb8 + 16UC1 depth), as a camera would publish it; its sequence
    number in `header.frame_id` (8 digits) to match an echo to its ping."""
    rng = np.random.default_rng(7)
    rgb = rng.integers(0, 256, size=(c.HEIGHT, c.WIDTH, 3), dtype=np.uint8)
    depth = rng.integers(400, 4000, size=(c.HEIGHT, c.WIDTH), dtype=np.uint16)
    f = msg.RgbdFrame()
    f.header.frame_id = f"{seq:08d}"
    f.camera_info.width, f.camera_info.height = c.WIDTH, c.HEIGHT
    # The bytes once, as `bytes`: what Publisher.publish converts cheapest (a NumPy array is
    # copied once more first).
    f.rgb = msg.Image(
        height=c.HEIGHT, width=c.WIDTH, encoding="rgb8", step=c.WIDTH * 3, data=rgb.tobytes()
    )
    f.depth = msg.Image(
        height=c.HEIGHT, width=c.WIDTH, encoding="16UC1", step=c.WIDTH * 2, data=depth.tobytes()
    )
    return f


def sample_of(a: np.ndarray):
    """The received sample an array borrows (robocog's SampleBuffer), or None."""
    o = a
    for _ in range(8):
        if hasattr(o, "is_shm"):
            return o
        o = getattr(o, "base", None) if not isinstance(o, memoryview) else o.obj
        if o is None:
            return None
    return None


# ---------------------------------------------------------------------------------------------


def echo(args, node: robocog.Node) -> None:
    pong = node.publisher(c.PONG, msg.Ping)
    node.subscribe(c.PING, msg.Ping, pong.publish)
    frame_back = node.publisher(c.FRAME_BACK, msg.RgbdFrame)
    node.subscribe(c.FRAME, msg.RgbdFrame, frame_back.publish, queue=4)

    count_report = node.publisher(c.COUNT_REPORT, msg.Ping)
    frame_report = node.publisher(c.FRAME_COUNT_REPORT, msg.Ping)

    def reporter(pub):
        def report(got: int, ns: int, extra: int) -> None:
            c.say(f"robocog echo: counted {got} in {ns / 1e9:.2f} s")
            pub.publish(msg.Ping(sent_ns=ns, data=c.report_data(got, extra)))

        return report

    counts = c.Tally(reporter(count_report), args.expected)
    frames = c.Tally(reporter(frame_report))

    def on_frame(f: msg.RgbdFrame) -> None:
        # What a consumer starts with: the pixels as NumPy arrays (views of the sample).
        rgb, depth = images.rgb(f), images.depth_mm(f)
        s = sample_of(rgb)
        frames.one(extra=int(bool(s is not None and s.is_shm and not depth.flags.owndata)))

    # As deep a queue as the Rust echo's (65536): the count measures the callback, not drops.
    node.subscribe(c.COUNT, msg.Counter64, lambda m: counts.one(), queue=65536)
    # Frames held in the queue hold shared-memory buffers of the publisher's pool (32 MB).
    node.subscribe(c.FRAME_COUNT, msg.RgbdFrame, on_frame, queue=4)
    node.timer(0.1, lambda: (counts.check(), frames.check()))
    c.ready("robocog echo")
    node.spin()


class Probe:
    def __init__(self, args, node: robocog.Node):
        self.args = args
        self.node = node
        self.ping_pub = node.publisher(c.PING, msg.Ping)
        self.count_pub = node.publisher(c.COUNT, msg.Counter64)
        self.frame_pub = node.publisher(c.FRAME, msg.RgbdFrame)
        self.frame_count_pub = node.publisher(c.FRAME_COUNT, msg.RgbdFrame)
        self.seq = 0
        self.t_back = 0
        self.back_len = -1
        self.reports: dict[str, msg.Ping] = {}
        # What the received frames were: arrays owning their data (a copy), in shared memory.
        self.frames_owning = 0
        self.frames_shm = 0
        self.frames_seen = 0
        self.last_frame: msg.RgbdFrame | None = None
        node.subscribe(c.PONG, msg.Ping, self.on_pong)
        node.subscribe(c.FRAME_BACK, msg.RgbdFrame, self.on_frame_back, queue=4)
        node.subscribe(c.COUNT_REPORT, msg.Ping, lambda m: self.reports.__setitem__("count", m))
        node.subscribe(
            c.FRAME_COUNT_REPORT, msg.Ping, lambda m: self.reports.__setitem__("frames", m)
        )

    # -- callbacks (on this thread, inside spin_once)

    def on_pong(self, m: msg.Ping) -> None:
        if m.sent_ns == self.seq:
            self.t_back = c.now_ns()
            self.back_len = len(m.data)

    def on_frame_back(self, f: msg.RgbdFrame) -> None:
        if f.header.frame_id != f"{self.seq:08d}":
            return
        rgb, depth = images.rgb(f), images.depth_mm(f)
        if rgb.shape != (c.HEIGHT, c.WIDTH, 3) or depth.shape != (c.HEIGHT, c.WIDTH):
            raise ValueError(f"echo of a frame of the wrong shape: {rgb.shape}, {depth.shape}")
        c.touch(rgb, depth)
        self.t_back = c.now_ns()
        self.back_len = rgb.nbytes + depth.nbytes
        self.frames_seen += 1
        self.frames_owning += int(rgb.flags.owndata or depth.flags.owndata)
        s = sample_of(rgb)
        self.frames_shm += int(s is not None and s.is_shm)
        self.last_frame = f

    # -- helpers

    def wait(self, pred, timeout_s: float) -> bool:
        deadline = c.now_ns() + timeout_s * 1e9
        while not pred():
            left = (deadline - c.now_ns()) / 1e9
            if left <= 0:
                return False
            self.node.spin_once(left)
        return True

    def once(self, publish, message, timeout_s: float) -> float | None:
        """One round trip: one-way µs, or None when no answer came in time."""
        self.seq += 1
        self.t_back = 0
        t0 = c.now_ns()
        publish(message)
        if not self.wait(lambda: self.t_back != 0, timeout_s):
            return None
        return (self.t_back - t0) / 2e3

    def until_answered(self, publish, make, what: str, each_s: float) -> None:
        t0 = c.now_ns()
        while True:
            m = make()
            if self.once(publish, m, each_s) is not None:
                c.say(f"robocog probe: the echo answers {what} ({(c.now_ns() - t0) / 1e9:.1f} s)")
                return
            if c.now_ns() - t0 > 30e9:
                raise SystemExit(f"robocog probe: no answer to {what} after 30 s")

    def latency(self, publish, make, n: int, warm: int, what: str) -> list[float]:
        out = []
        for i in range(n + warm):
            us = self.once(publish, make(), c.REPLY_TIMEOUT_S)
            if us is None:
                raise SystemExit(f"robocog probe: a {what} got no answer in {c.REPLY_TIMEOUT_S} s")
            if i >= warm:
                out.append(us)
        return out

    def one_way(self, publish, make, secs: float, max_n: int, report: str) -> dict:
        """Publish as fast as this thread can for `secs` (at most `max_n`), then wait for the
        echo's count."""
        self.reports.pop(report, None)
        n = 0
        t0 = c.now_ns()
        end = t0 + secs * 1e9
        while n < max_n:
            publish(make(n))
            n += 1
            if (n & 63 == 0 or max_n < 100_000) and c.now_ns() >= end:
                break
        send_s = (c.now_ns() - t0) / 1e9
        if not self.wait(lambda: report in self.reports, 60.0):
            raise SystemExit(f"robocog probe: the echo did not report its {report} count in 60 s")
        r = self.reports[report]
        got = int.from_bytes(bytes(r.data[:8]), "little")
        extra = int.from_bytes(bytes(r.data[8:16]), "little") if len(r.data) >= 16 else None
        return {
            "sent": n,
            "received": got,
            "send_msgs_per_s": n / max(send_s, 1e-9),
            "msgs_per_s": got / max(r.sent_ns / 1e9, 1e-9),
            "received_shm": extra,
        }


def probe(args, node: robocog.Node) -> None:
    p = Probe(args, node)
    out: dict = {"end": "robocog"}
    ping = msg.Ping(data=b"\xab" * c.SMALL_BYTES)

    def make_ping():
        ping.sent_ns = p.seq + 1
        return ping

    p.until_answered(p.ping_pub.publish, make_ping, "64 B pings", 0.25)
    c.say(f"robocog probe: latency 64 B ({args.n_small} round trips, {args.warm_small} warm-up)")
    lat = p.latency(p.ping_pub.publish, make_ping, args.n_small, args.warm_small, "64 B ping")
    out["small_p50_us"], out["small_p99_us"] = c.summarise(lat)

    node_sleep(node, 0.3)
    c.say(f"robocog probe: Counter64 one way for {args.secs} s (at most {args.max_count})")
    counter = msg.Counter64()

    def make_count(i):
        counter.value = i
        return counter

    tp = p.one_way(p.count_pub.publish, make_count, args.secs, args.max_count, "count")
    out.update({f"small_{k}": v for k, v in tp.items() if v is not None})

    if args.frames:
        frame = frame_message()

        def make_frame(*_):
            frame.header.frame_id = f"{p.seq + 1:08d}"
            return frame

        p.until_answered(p.frame_pub.publish, make_frame, "RGB-D frames", 1.0)
        p.frames_seen = p.frames_owning = p.frames_shm = 0
        c.say(f"robocog probe: latency RGB-D ({args.n_frames} round trips, {args.warm_frames} warm-up)")
        lat = p.latency(p.frame_pub.publish, make_frame, args.n_frames, args.warm_frames, "frame")
        out["frame_p50_us"], out["frame_p99_us"] = c.summarise(lat)
        out["frame_bytes"] = len(robocog.encode(frame))
        out["frames_received"] = p.frames_seen
        out["frames_arrays_owning_data"] = p.frames_owning
        out["frames_in_shm"] = p.frames_shm
        node_sleep(node, 0.3)
        c.say(f"robocog probe: RGB-D frames one way for {args.secs} s")
        tp = p.one_way(p.frame_count_pub.publish, make_frame, args.secs, 10**9, "frames")
        out.update({f"frame_{k}": v for k, v in tp.items() if v is not None})
        out["frame_publisher_shm_fallbacks"] = node.counter(f"shm_fallback/{c.FRAME_COUNT}")
        out.update(frame_steps(node, frame, p.last_frame, 20 if args.quick else 100))
    c.emit(out)


def frame_steps(node: robocog.Node, frame: msg.RgbdFrame, received: msg.RgbdFrame, n: int) -> dict:
    """Each step of a Python frame's way alone, medians of `n` (µs): what the round trip is
    made of. Published on a topic nobody subscribes to (encoded into shared memory all the
    same)."""

    def median_us(fn) -> float:
        t = []
        for _ in range(n):
            t0 = c.now_ns()
            fn()
            t.append((c.now_ns() - t0) / 1e3)
        return c.summarise(t)[0]

    pub = node.publisher("bench/frame_steps", msg.RgbdFrame)
    as_numpy = msg.RgbdFrame(
        header=frame.header,
        camera_info=frame.camera_info,
        rgb=dataclasses.replace(frame.rgb, data=np.frombuffer(frame.rgb.data, np.uint8)),
        depth=dataclasses.replace(frame.depth, data=np.frombuffer(frame.depth.data, np.uint8)),
    )
    rgb, depth = images.rgb(received), images.depth_mm(received)
    return {
        "step_publish_bytes_us": median_us(lambda: pub.publish(frame)),
        "step_publish_received_us": median_us(lambda: pub.publish(received)),
        "step_publish_numpy_us": median_us(lambda: pub.publish(as_numpy)),
        "step_encode_us": median_us(lambda: robocog.encode(frame)),
        "step_views_us": median_us(lambda: (images.rgb(received), images.depth_mm(received))),
        "step_read_all_bytes_us": median_us(lambda: c.touch(rgb, depth)),
        "step_copy_us": median_us(lambda: (bytes(received.rgb.data), bytes(received.depth.data))),
    }


def node_sleep(node: robocog.Node, s: float) -> None:
    node.spin(s)


def templates(args) -> None:
    """The CDR bytes of each message the plain zenoh client sends, and where it patches them."""
    os.makedirs(args.out, exist_ok=True)
    mark = 0x1122334455667788
    mark_b = mark.to_bytes(8, "little")
    index = {}

    def write(name: str, m, **offsets) -> bytes:
        b = robocog.encode(m)
        with open(os.path.join(args.out, f"{name}.cdr"), "wb") as f:
            f.write(b)
        index[name] = {"len": len(b), **offsets}
        return b

    b = robocog.encode(msg.Ping(sent_ns=mark, data=b"\xab" * c.SMALL_BYTES))
    write("ping", msg.Ping(sent_ns=0, data=b"\xab" * c.SMALL_BYTES), sent_ns=b.index(mark_b))
    b = robocog.encode(msg.Ping(sent_ns=mark, data=b"\xee" * 16))
    write("report", msg.Ping(data=b"\0" * 16), sent_ns=b.index(mark_b), data=b.index(b"\xee" * 16))
    b = robocog.encode(msg.Counter64(value=mark))
    write("count", msg.Counter64(), value=b.index(mark_b))
    f = frame_message(0)
    b = robocog.encode(f)
    write(
        "frame",
        f,
        frame_id=b.index(b"00000000"),
        rgb=b.index(f.rgb.data[:4096]),
        rgb_len=len(f.rgb.data),
        depth=b.index(f.depth.data[:4096]),
        depth_len=len(f.depth.data),
    )
    with open(os.path.join(args.out, "index.json"), "w") as fh:
        json.dump(index, fh)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--role", choices=["echo", "probe", "templates"], required=True)
    ap.add_argument("--connect", default="")
    ap.add_argument("--namespace", default="bench-python")
    ap.add_argument("--out", default="")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--frames", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument("--expected", type=int, default=0, help="echo: counts end at this many")
    ap.add_argument("--max-count", type=int, default=10**9, help="probe: send at most this many")
    ap.add_argument("--secs", type=float, default=None, help="probe: one-way runs (s)")
    args = ap.parse_args()
    args.n_small, args.warm_small = (200, 20) if args.quick else (2000, 200)
    args.n_frames, args.warm_frames = (50, 10) if args.quick else (300, 30)
    if args.secs is None:
        args.secs = 1.0 if args.quick else 3.0
    if args.role == "templates":
        return templates(args)
    argv = ["--connect", args.connect, "--namespace", args.namespace]
    node = robocog.Node(f"bench-python-{args.role}", argv)
    if args.role == "echo":
        echo(args, node)
    else:
        probe(args, node)


if __name__ == "__main__":
    main()

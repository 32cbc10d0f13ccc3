"""`scripts/bench python`: one end on the bus as a plain eclipse-zenoh Python client, no robocog.

It puts and subscribes the same CDR bytes on the same keys as robocog's publishers and
subscribers (`robocog/<ns>/t/<topic>`, encoding `application/cdr;<type>`); the bytes come from
the templates `robocog_end.py --role templates` wrote (robocog.encode), patched in place
(sequence numbers, counts). A zenoh client of the router, multicast scouting off, shared memory
on: large payloads (frames) go through zenoh's shared-memory provider, as a zenoh user would
send them.

--role echo: puts every sample of bench/ping back on bench/pong and of bench/frame on
    bench/frame_back, as received (no decode, no copy: a relay); counts bench/count and
    bench/frame_count (frames read as NumPy arrays: zenoh-python hands out bytes, so a copy) and
    reports each count on bench/count_report and bench/frame_count_report. Prints `ready`, runs
    until SIGTERM.
--role probe: ping-pong of the 64 B Ping and of the RGB-D frame (one-way = round trip / 2, every
    byte of the frame read), then Counter64 payloads and frames one way. Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import struct
import sys
import threading
import time

import numpy as np
import zenoh

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common as c  # noqa: E402

SHM_POOL_BYTES = 32 * 1024 * 1024  # as robocog's publishers


class Templates:
    def __init__(self, folder: str):
        with open(os.path.join(folder, "index.json")) as f:
            self.index = json.load(f)
        self.bytes = {}
        for name in self.index:
            with open(os.path.join(folder, f"{name}.cdr"), "rb") as f:
                self.bytes[name] = f.read()

    def off(self, name: str, field: str) -> int:
        return self.index[name][field]


def open_session(endpoint: str) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("transport/shared_memory/enabled", "true")
    return zenoh.open(conf)


def encoding(type_name: str) -> zenoh.Encoding:
    return zenoh.Encoding("application/cdr").with_schema(type_name)


def publisher(s: zenoh.Session, ns: str, topic: str, type_name: str) -> zenoh.Publisher:
    return s.declare_publisher(
        c.key(ns, topic),
        encoding=encoding(type_name),
        congestion_control=zenoh.CongestionControl.BLOCK,
    )


def frame_arrays(t: Templates, data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """The pixels of a received frame's bytes (laid out as the template's)."""
    rgb = np.frombuffer(data, np.uint8, t.off("frame", "rgb_len"), t.off("frame", "rgb"))
    depth = np.frombuffer(
        data, np.dtype("<u2"), t.off("frame", "depth_len") // 2, t.off("frame", "depth")
    )
    return rgb.reshape(c.HEIGHT, c.WIDTH, 3), depth.reshape(c.HEIGHT, c.WIDTH)


# ---------------------------------------------------------------------------------------------


def echo(args, t: Templates, s: zenoh.Session) -> None:
    ns = args.namespace
    pong = publisher(s, ns, c.PONG, "robocog.Ping")
    frame_back = publisher(s, ns, c.FRAME_BACK, "robocog.RgbdFrame")
    keep = [
        s.declare_subscriber(c.key(ns, c.PING), lambda smp: pong.put(smp.payload)),
        s.declare_subscriber(c.key(ns, c.FRAME), lambda smp: frame_back.put(smp.payload)),
    ]

    def reporter(topic: str):
        pub = publisher(s, ns, topic, "robocog.Ping")

        def report(got: int, ns_: int, extra: int) -> None:
            c.say(f"zenoh echo: counted {got} in {ns_ / 1e9:.2f} s")
            b = bytearray(t.bytes["report"])
            struct.pack_into("<Q", b, t.off("report", "sent_ns"), ns_)
            b[t.off("report", "data") : t.off("report", "data") + 16] = c.report_data(got, extra)
            pub.put(bytes(b))

        return report

    counts = c.Tally(reporter(c.COUNT_REPORT))
    frames = c.Tally(reporter(c.FRAME_COUNT_REPORT))

    def on_frame(smp: zenoh.Sample) -> None:
        # The pixels as NumPy arrays: zenoh-python gives the payload as bytes (a copy).
        shm = smp.payload.as_shm() is not None
        frame_arrays(t, smp.payload.to_bytes())
        frames.one(extra=int(shm))

    keep.append(s.declare_subscriber(c.key(ns, c.COUNT), lambda smp: counts.one()))
    keep.append(s.declare_subscriber(c.key(ns, c.FRAME_COUNT), on_frame))
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    c.ready("zenoh echo")
    while not stop.wait(0.1):
        counts.check()
        frames.check()
    s.close()


class Watchdog:
    """Ends the process when a blocking receive waits too long (zenoh-python's `recv` has no
    time-out)."""

    def __init__(self, what: str):
        self.what = what
        self.deadline = None
        threading.Thread(target=self._run, daemon=True).start()

    def arm(self, secs: float) -> None:
        self.deadline = time.monotonic() + secs

    def disarm(self) -> None:
        self.deadline = None

    def _run(self) -> None:
        while True:
            time.sleep(0.2)
            d = self.deadline
            if d is not None and time.monotonic() > d:
                c.say(f"zenoh probe: no answer to {self.what} in time")
                os._exit(3)


def probe(args, t: Templates, s: zenoh.Session) -> None:
    ns = args.namespace
    out: dict = {"end": "zenoh-python"}
    dog = Watchdog("the probe")
    ping_pub = publisher(s, ns, c.PING, "robocog.Ping")
    pongs = s.declare_subscriber(c.key(ns, c.PONG))
    count_pub = publisher(s, ns, c.COUNT, "robocog.Counter64")
    reports = s.declare_subscriber(c.key(ns, c.COUNT_REPORT))
    frame_pub = publisher(s, ns, c.FRAME, "robocog.RgbdFrame")
    frames_back = s.declare_subscriber(c.key(ns, c.FRAME_BACK))
    frame_count_pub = publisher(s, ns, c.FRAME_COUNT, "robocog.RgbdFrame")
    frame_reports = s.declare_subscriber(c.key(ns, c.FRAME_COUNT_REPORT))

    ping = bytearray(t.bytes["ping"])
    seq_at = t.off("ping", "sent_ns")
    seq = 0

    def ping_once(block: bool, timeout_s: float) -> float | None:
        nonlocal seq
        seq += 1
        struct.pack_into("<Q", ping, seq_at, seq)
        t0 = c.now_ns()
        ping_pub.put(bytes(ping))
        end = t0 + timeout_s * 1e9
        while True:
            if block:
                dog.arm(timeout_s)
                smp = pongs.recv()
                dog.disarm()
            else:
                smp = pongs.try_recv()
                if smp is None:
                    if c.now_ns() > end:
                        return None
                    time.sleep(0.001)
                    continue
            b = smp.payload.to_bytes()
            if struct.unpack_from("<Q", b, seq_at)[0] == seq:
                return (c.now_ns() - t0) / 2e3

    t0 = c.now_ns()
    while ping_once(False, 0.25) is None:
        if c.now_ns() - t0 > 30e9:
            raise SystemExit("zenoh probe: no answer to pings after 30 s")
    c.say(f"zenoh probe: latency 64 B ({args.n_small} round trips, {args.warm_small} warm-up)")
    lat = [ping_once(True, c.REPLY_TIMEOUT_S) for _ in range(args.n_small + args.warm_small)]
    out["small_p50_us"], out["small_p99_us"] = c.summarise(lat[args.warm_small :])

    def wait_report(sub) -> tuple[int, int, int]:
        end = time.monotonic() + 60
        while (smp := sub.try_recv()) is None:
            if time.monotonic() > end:
                raise SystemExit("zenoh probe: the echo did not report its count in 60 s")
            time.sleep(0.01)
        b = smp.payload.to_bytes()
        ns_ = struct.unpack_from("<Q", b, t.off("report", "sent_ns"))[0]
        d = t.off("report", "data")
        got, extra = struct.unpack_from("<QQ", b, d)
        return got, ns_, extra

    def one_way(put, secs: float, sub, prefix: str) -> None:
        n = 0
        t0 = c.now_ns()
        end = t0 + secs * 1e9
        while True:
            put(n)
            n += 1
            if c.now_ns() >= end:
                break
        send_s = (c.now_ns() - t0) / 1e9
        got, ns_, extra = wait_report(sub)
        out[f"{prefix}_sent"] = n
        out[f"{prefix}_received"] = got
        out[f"{prefix}_send_msgs_per_s"] = n / max(send_s, 1e-9)
        out[f"{prefix}_msgs_per_s"] = got / max(ns_ / 1e9, 1e-9)
        out[f"{prefix}_received_shm"] = extra

    time.sleep(0.3)
    c.say(f"zenoh probe: Counter64 one way for {args.secs} s")
    count = bytearray(t.bytes["count"])
    value_at = t.off("count", "value")

    def put_count(i: int) -> None:
        struct.pack_into("<Q", count, value_at, i)
        count_pub.put(bytes(count))

    one_way(put_count, args.secs, reports, "small")

    if args.frames:
        frame = t.bytes["frame"]
        id_at = t.off("frame", "frame_id")
        try:
            shm = zenoh.shm.ShmProvider.default_backend(SHM_POOL_BYTES)
        except Exception as e:  # noqa: BLE001
            c.say(f"zenoh probe: no shared memory ({e}): frames are copied")
            shm = None
        out["frame_publisher_shm"] = shm is not None
        fallbacks = 0

        def frame_payload(i: int):
            nonlocal fallbacks
            tag = b"%08d" % (i % 100_000_000)
            if shm is not None:
                try:
                    buf = shm.alloc(len(frame), zenoh.shm.GarbageCollect())
                    buf[:] = frame  # the one copy into shared memory
                    buf[id_at : id_at + 8] = tag
                    return buf
                except Exception:  # noqa: BLE001
                    fallbacks += 1
            b = bytearray(frame)
            b[id_at : id_at + 8] = tag
            return bytes(b)

        fseq = 0
        seen = shm_seen = 0

        def frame_once(block: bool, timeout_s: float) -> float | None:
            nonlocal fseq, seen, shm_seen
            fseq += 1
            tag = b"%08d" % fseq
            t0 = c.now_ns()
            frame_pub.put(frame_payload(fseq))
            end = t0 + timeout_s * 1e9
            while True:
                if block:
                    dog.arm(timeout_s)
                    smp = frames_back.recv()
                    dog.disarm()
                else:
                    smp = frames_back.try_recv()
                    if smp is None:
                        if c.now_ns() > end:
                            return None
                        time.sleep(0.001)
                        continue
                in_shm = smp.payload.as_shm() is not None
                data = smp.payload.to_bytes()  # zenoh-python: the bytes, copied
                if data[id_at : id_at + 8] != tag:
                    continue
                rgb, depth = frame_arrays(t, data)
                c.touch(rgb, depth)
                seen += 1
                shm_seen += int(in_shm)
                return (c.now_ns() - t0) / 2e3

        t0 = c.now_ns()
        while frame_once(False, 1.0) is None:
            if c.now_ns() - t0 > 30e9:
                raise SystemExit("zenoh probe: no answer to frames after 30 s")
        seen = shm_seen = 0
        c.say(f"zenoh probe: latency RGB-D ({args.n_frames} round trips, {args.warm_frames} warm-up)")
        lat = [frame_once(True, c.REPLY_TIMEOUT_S) for _ in range(args.n_frames + args.warm_frames)]
        out["frame_p50_us"], out["frame_p99_us"] = c.summarise(lat[args.warm_frames :])
        out["frame_bytes"] = len(frame)
        out["frames_received"] = seen
        out["frames_in_shm"] = shm_seen
        time.sleep(0.3)
        c.say(f"zenoh probe: RGB-D frames one way for {args.secs} s")
        one_way(lambda i: frame_count_pub.put(frame_payload(i)), args.secs, frame_reports, "frame")
        out["frame_publisher_shm_fallbacks"] = fallbacks
    c.emit(out)
    s.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--role", choices=["echo", "probe"], required=True)
    ap.add_argument("--connect", required=True)
    ap.add_argument("--namespace", default="bench-python")
    ap.add_argument("--templates", required=True)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--frames", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument("--secs", type=float, default=None)
    args = ap.parse_args()
    args.n_small, args.warm_small = (200, 20) if args.quick else (2000, 200)
    args.n_frames, args.warm_frames = (50, 10) if args.quick else (300, 30)
    if args.secs is None:
        args.secs = 1.0 if args.quick else 3.0
    t = Templates(args.templates)
    s = open_session(args.connect)
    if args.role == "echo":
        echo(args, t, s)
    else:
        probe(args, t, s)


if __name__ == "__main__":
    main()

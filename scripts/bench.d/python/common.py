"""What both Python ends of `scripts/bench python` share (no robocog import here: the plain zenoh
client uses it too): the topics, percentiles as the Rust benchmarks take them, the read of every
byte of a frame, and the one-line JSON the script collects."""

from __future__ import annotations

import json
import sys
import time

import numpy as np

# The bus topics of the benchmark (those of `interfaces::topics` for ping, pong, count and its
# report, which the Rust `bench_bus_machines` echo and probe use), and two of this benchmark's own
# for frames counted one way.
PING = "bench/ping"  # msg.Ping, probe -> echo
PONG = "bench/pong"  # msg.Ping, echo -> probe
FRAME = "bench/frame"  # msg.RgbdFrame, probe -> echo
FRAME_BACK = "bench/frame_back"  # msg.RgbdFrame, echo -> probe
COUNT = "bench/count"  # msg.Counter64, probe -> echo, counted
COUNT_REPORT = "bench/count_report"  # msg.Ping: sent_ns = ns first..last, data = count (u64 LE)
FRAME_COUNT = "bench/frame_count"  # msg.RgbdFrame, probe -> echo, counted
FRAME_COUNT_REPORT = "bench/frame_count_report"  # msg.Ping, as COUNT_REPORT

SMALL_BYTES = 64  # the data of the small Ping (as the Rust benchmarks' "64 B")
WIDTH, HEIGHT = 640, 480
# A count ends when this long passes without a message (the Rust echo waits 5 s).
SILENCE_S = 1.0
# How long a round trip may take before the run fails.
REPLY_TIMEOUT_S = 5.0


def key(namespace: str, topic: str) -> str:
    """The zenoh key of a topic: `robocog/<ns>/t/<topic>`."""
    return f"robocog/{namespace}/t/{topic}"


def pct(sorted_values: list[float], p: float) -> float:
    if not sorted_values:
        return float("nan")
    i = round((len(sorted_values) - 1) * p)
    return sorted_values[min(i, len(sorted_values) - 1)]


def summarise(one_way_us: list[float]) -> tuple[float, float]:
    """p50 and p99 (µs)."""
    s = sorted(one_way_us)
    return pct(s, 0.5), pct(s, 0.99)


def touch(*arrays: np.ndarray) -> int:
    """Read every byte once, eight at a time (as the Rust benchmark's `touch`): what a consumer
    scanning the pixels does at least."""
    total = 0
    for a in arrays:
        flat = a.reshape(-1)
        n8 = flat.nbytes // 8 * 8
        b = flat.view(np.uint8)
        total += int(b[:n8].view(np.uint64).sum(dtype=np.uint64)) + int(b[n8:].sum())
    return total


def now_ns() -> int:
    return time.perf_counter_ns()


def say(*args) -> None:
    print(*args, file=sys.stderr, flush=True)


def ready(what: str) -> None:
    print(f"ready {what}", flush=True)


def emit(figures: dict) -> None:
    print(json.dumps(figures), flush=True)


class Tally:
    """The receiving end of a one-way run: counts messages from the first on, and ends the run
    (calls `report(count, ns from the first to the last)`) once `expected` are in or after
    `SILENCE_S` without one. `check()` is called now and then to notice the silence. Callers
    on several threads hold `lock`."""

    def __init__(self, report, expected: int = 0):
        import threading

        self.report = report
        self.expected = expected
        self.lock = threading.Lock()
        self.got = 0
        self.first = 0
        self.last = 0
        self.extra = 0  # what the receiver counts besides (frames that came in shared memory)

    def one(self, extra: int = 0) -> None:
        t = now_ns()
        with self.lock:
            if self.got == 0:
                self.first = t
            self.got += 1
            self.extra += extra
            self.last = t
            done = self.expected and self.got >= self.expected
        if done:
            self._end()

    def check(self) -> None:
        with self.lock:
            idle = self.got and now_ns() - self.last > SILENCE_S * 1e9
        if idle:
            self._end()

    def _end(self) -> None:
        with self.lock:
            got, ns, extra = self.got, self.last - self.first, self.extra
            self.got = self.extra = 0
        if got:
            self.report(got, ns, extra)


def report_data(got: int, extra: int) -> bytes:
    """The data of a count report: the count (u64 LE), as the Rust echo sends it, then what the
    receiver counted besides (u64 LE)."""
    return got.to_bytes(8, "little") + extra.to_bytes(8, "little")

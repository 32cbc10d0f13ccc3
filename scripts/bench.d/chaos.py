#!/usr/bin/env python3
"""The chaos matrix's driver (scripts/bench chaos): for every cell (a component, a phase of the
touch game), one `robocog launch` of the game with the simulated person (scenario `still`), the
component killed with SIGKILL the moment the phase begins, and a verdict on what the person saw:

- the scenario completed (every expectation met, the launcher exited 0);
- the launcher restarted the killed component;
- the person never had to say a command again;
- the robot said nothing that contradicts what it did: with a ball held still in front of it,
  "I lost the ball", "out of my sight", "I can't reach it", "I am not touching the ball", ...
  are all untrue (what the robot said comes from `speech/say`, through `robocog topic echo`).

Prints the matrix (one row per component, one column per phase), what failed in each failed
cell, keeps every cell's output in OUT_DIR, and as its last line one JSON object.

Usage: chaos.py BIN_DIR OUT_DIR [--components a,b,...] [--phases p,q,...]
"""
import argparse
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time

COMPONENTS = ["deep_representation", "joint_motor", "body_inverse_kinematics", "ball_tracker",
              "rgbd", "speech_generator", "dialogs", "speech_recognition", "executive"]
# Each phase of the touch game, and the output line that starts it.
PHASES = {
    "greeting": 'person: says "hello"',
    "scan": "[state] command:scan_ball:",
    "tracking": "person: sees gaze within",
    "reaching": "-> arm/reaching/moving",
    "touching": "-> arm/reaching/touching",
    "homing": "-> arm/homing",
    "goodbye": "[state] command:quit:",
}
# What the robot must not say while a person holds the ball still in front of it.
UNTRUE = ["I cannot find the ball", "The ball is out of my sight", "I lost the ball",
          "I can't reach it", "Something is wrong with my arm", "I have not seen the ball yet",
          "I am not touching the ball", "That is not a command of this game",
          "I think I touched it"]
CELL_LIMIT_S = 240
STARTED = re.compile(r"started (\S+) \(pid (\d+)\)")
ROUTER = re.compile(r"router (tcp/[0-9.]+:\d+)")


class Cell:
    def __init__(self, component, phase):
        self.component, self.phase = component, phase
        self.lines, self.said = [], []
        self.pids, self.router = {}, None
        self.killed_at = None
        self.exit = None
        self.cond = threading.Condition()


def read_lines(stream, sink, cell):
    for line in stream:
        with cell.cond:
            sink.append(line.rstrip("\n"))
            cell.cond.notify_all()


def run_cell(bin_dir, root, out_dir, n, cell):
    ns = f"chaos-{os.getpid()}-{n}"
    launch = subprocess.Popen(
        [f"{bin_dir}/robocog", "launch", "launch/touch_the_ball.toml", "--set", "scenario=still",
         "--set", "panel=false", "--namespace", ns, "--router", "tcp/127.0.0.1:0",
         "--color", "never"],
        cwd=root, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
    threading.Thread(target=read_lines, args=(launch.stdout, cell.lines, cell),
                     daemon=True).start()
    echo = None
    said_raw = []
    trigger = PHASES[cell.phase]
    deadline = time.monotonic() + CELL_LIMIT_S
    seen = 0
    while launch.poll() is None and time.monotonic() < deadline:
        with cell.cond:
            cell.cond.wait(timeout=0.05)
            new = cell.lines[seen:]
            seen = len(cell.lines)
        for line in new:
            m = STARTED.search(line)
            if m and line.lstrip().startswith("robocog |"):
                cell.pids[m.group(1)] = int(m.group(2))
            m = ROUTER.search(line)
            if m and cell.router is None:
                cell.router = m.group(1)
                echo = subprocess.Popen(
                    [f"{bin_dir}/robocog", "topic", "echo", "speech/say", "--namespace", ns,
                     "--connect", cell.router],
                    stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, bufsize=1)
                threading.Thread(target=read_lines, args=(echo.stdout, said_raw, cell),
                                 daemon=True).start()
            if cell.killed_at is None and trigger in line and cell.component in cell.pids:
                try:
                    os.kill(cell.pids[cell.component], signal.SIGKILL)
                    cell.killed_at = line.strip()
                except ProcessLookupError:
                    pass
    if launch.poll() is None:
        launch.send_signal(signal.SIGTERM)
        try:
            launch.wait(timeout=20)
        except subprocess.TimeoutExpired:
            launch.kill()
            launch.wait()
        cell.exit = "timed out"
    else:
        cell.exit = launch.returncode
    time.sleep(0.3)
    if echo is not None:
        echo.terminate()
        try:
            echo.wait(timeout=5)
        except subprocess.TimeoutExpired:
            echo.kill()
    for line in said_raw:
        try:
            cell.said.append(json.loads(line).get("text", ""))
        except ValueError:
            continue
    with open(os.path.join(out_dir, f"{cell.component}-{cell.phase}.log"), "w") as f:
        f.write("\n".join(cell.lines) + "\n\nthe robot said:\n" + "\n".join(cell.said) + "\n")


def verdict(cell):
    """The reasons a cell failed (none: it passed)."""
    why = []
    if cell.killed_at is None:
        why.append("never killed (the phase did not come)")
    if cell.exit != 0:
        last = [l for l in cell.lines if "failed" in l or "expected" in l][-1:]
        why.append(f"the game did not complete (exit {cell.exit}){': ' + last[0] if last else ''}")
    if cell.killed_at is not None and not any(
            f"{cell.component} stopped" in l and "restart 1/" in l for l in cell.lines):
        why.append("not restarted")
    again = [l for l in cell.lines if "says it again" in l]
    if again:
        why.append(f"the person repeated a command {len(again)}x: "
                   + again[0].split("person: ", 1)[-1])
    untrue = [s for s in cell.said if any(u.lower() in s.lower() for u in UNTRUE)]
    if untrue:
        why.append("the robot said: " + "; ".join(f'"{s}"' for s in untrue))
    return why


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("bin_dir")
    ap.add_argument("out_dir")
    ap.add_argument("--components", default=",".join(COMPONENTS))
    ap.add_argument("--phases", default=",".join(PHASES))
    a = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    comps = [c for c in a.components.split(",") if c]
    phases = [p for p in a.phases.split(",") if p]
    for p in phases:
        if p not in PHASES:
            sys.exit(f"unknown phase {p!r}: the phases are {', '.join(PHASES)}")
    for c in comps:
        if c not in COMPONENTS:
            sys.exit(f"unknown component {c!r}: the components are {', '.join(COMPONENTS)}")
    os.makedirs(a.out_dir, exist_ok=True)
    started = time.monotonic()
    results = {}
    total = len(comps) * len(phases)
    n = 0
    for c in comps:
        for p in phases:
            n += 1
            cell = Cell(c, p)
            run_cell(a.bin_dir, root, a.out_dir, n, cell)
            why = verdict(cell)
            results[(c, p)] = why
            mins = (time.monotonic() - started) / 60
            print(f"  cell {n} of {total}: {c} killed at {p}: "
                  f"{'passed' if not why else 'FAILED: ' + ' | '.join(why)} ({mins:.0f} min)",
                  file=sys.stderr, flush=True)

    print()
    print(f"chaos matrix: the touch game (scenario still), each component killed (SIGKILL) as "
          f"each phase begins; {os.cpu_count()} cores")
    print(f"{'component':24} " + " ".join(f"{p:>9}" for p in phases))
    for c in comps:
        print(f"{c:24} " + " ".join(f"{'ok' if not results[(c, p)] else 'FAIL':>9}"
                                    for p in phases))
    failed = {k: v for k, v in results.items() if v}
    if failed:
        print("\nfailed cells:")
        for (c, p), why in failed.items():
            print(f"  {c} at {p}: " + " | ".join(why))
    print(f"\nevery cell's output: {a.out_dir}")
    print(json.dumps({
        "cells": total,
        "cells_passed": total - len(failed),
        "cells_failed": len(failed),
        "repeated_commands": sum(1 for v in failed.values() for w in v if "repeated" in w),
        "untrue_sentences_cells": sum(1 for v in failed.values() for w in v
                                      if w.startswith("the robot said")),
        "incomplete_games": sum(1 for v in failed.values() for w in v
                                if w.startswith("the game did not")),
        "minutes": round((time.monotonic() - started) / 60, 1),
        "failed": sorted(f"{c}@{p}" for c, p in failed),
    }))
    # A failed cell is a figure of the matrix, not a failure of the benchmark.
    sys.exit(0)


if __name__ == "__main__":
    main()

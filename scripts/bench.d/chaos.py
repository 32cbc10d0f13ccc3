#!/usr/bin/env python3
"""The chaos matrix's driver (scripts/bench chaos): for every cell (a component, a phase of a
game), one `robocog launch` of the game, the component killed with SIGKILL the moment the phase
begins, and a verdict on what the person saw.

The touch game (`--game touch`): the simulated person plays the scenario `still`. A cell passes
when
- the scenario completed (every expectation met, the launcher exited 0);
- the launcher restarted the killed component;
- the person never had to say a command again;
- the robot said nothing that contradicts what it did: with a ball held still in front of it,
  "I lost the ball", "out of my sight", "I can't reach it", "I am not touching the ball", ...
  are all untrue (what the robot said comes from `speech/say`, through `robocog topic echo`).

The coach game (`--game coach`): one attack on the simulated field (its other robots standing
still, no random falls), a coach outside the graph (`sim_coach.Coach`) giving four panel
commands; the phases are each command in flight, a penalty (the GameController's, scripted) and
a fall (the robot knocked over while walking). A cell passes when
- the attack was played to its end and the launcher's components stopped cleanly;
- the launcher restarted the killed component;
- every command the coach gave reached the robot (it never had to give one again), and the
  robot never obeyed a command the coach did not give;
- the robot said nothing untrue: no "not responding" (the link never broke), no fall or penalty
  it did not have.

Prints the matrix (one row per component, one column per phase), what failed in each failed
cell, keeps every cell's output in OUT_DIR, and as its last line one JSON object.

Usage: chaos.py BIN_DIR OUT_DIR [--game touch|coach] [--components a,b,...] [--phases p,q,...]
"""
import argparse
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sim_coach import Coach  # noqa: E402

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

COACH_COMPONENTS = ["nao_bridge", "deep_representation", "speech_generator", "dialogs",
                    "speech_recognition", "executive"]
CONTROLLED = "RobotId { side: Us, number: 2 }"
# Each phase of the coach game's attack, and the field's line that starts it.
COACH_PHASES = {
    "go_to": "robot 2 obeys Some(GoToPosition)",
    "turn": "robot 2 obeys Some(Turn)",
    "search": "robot 2 obeys Some(SearchTheBall)",
    "dribble": "robot 2 obeys Some(GoToBallAndDribble)",
    "penalty": f"Penalised {{ robot: {CONTROLLED}",
    "fall": f"Fell {{ robot: {CONTROLLED}",
}
# The coach game at 3x; the scripted penalty (simulated s into PLAYING, while the robot turns).
COACH_SCALE = 3.0
PENALTY_AT_S, PENALTY_S = 15.0, 10.0
# Untrue on a field where the link never breaks, and (but in their phases) nobody falls or is
# penalised.
COACH_UNTRUE = {"The robot is not responding": None, "I fell": "fall",
                "I am still on the ground": "fall", "I am penalised": "penalty"}
CELL_LIMIT_S = 240
STARTED = re.compile(r"started (\S+) \(pid (\d+)\)")
ROUTER = re.compile(r"router (tcp/[0-9.]+:\d+)")


class Cell:
    def __init__(self, game, component, phase):
        self.game, self.component, self.phase = game, component, phase
        self.lines, self.said = [], []
        self.pids, self.router = {}, None
        self.killed_at = None
        # How many output lines there were when the component was killed.
        self.killed_line = None
        self.exit = None
        self.coach = None
        self.cond = threading.Condition()


def read_lines(stream, sink, cell):
    for line in stream:
        with cell.cond:
            sink.append(line.rstrip("\n"))
            cell.cond.notify_all()


def free_udp_ports(n):
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


def launch_args(cell, ns):
    common = ["--namespace", ns, "--router", "tcp/127.0.0.1:0", "--color", "never",
              "--set", "panel=false"]
    if cell.game == "touch":
        return ["launch/touch_the_ball.toml", "--set", "scenario=still"] + common
    debug, gc, command = free_udp_ports(3)
    sets = [f"time_scale={COACH_SCALE:g}", "passive_opponents=true", "passive_teammate=true",
            "falls_per_min=0", f"debug_port={debug}", f"gc_port={gc}",
            f"command_port={command}"]
    if cell.phase == "penalty":
        sets += [f"penalty_at_s={PENALTY_AT_S:g}", f"penalty_s={PENALTY_S:g}"]
    args = ["launch/nao_coach.toml"] + common
    for kv in sets:
        args += ["--set", kv]
    return args


def run_cell(bin_dir, root, out_dir, n, cell):
    ns = f"chaos-{os.getpid()}-{n}"
    launch = subprocess.Popen(
        [f"{bin_dir}/robocog", "launch"] + launch_args(cell, ns),
        cwd=root, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
    threading.Thread(target=read_lines, args=(launch.stdout, cell.lines, cell),
                     daemon=True).start()
    if cell.game == "coach":
        cell.coach = Coach(f"{bin_dir}/robocog", ns, COACH_SCALE)
    echo = None
    said_raw = []
    trigger = (PHASES if cell.game == "touch" else COACH_PHASES)[cell.phase]
    deadline = time.monotonic() + CELL_LIMIT_S
    seen = 0
    knock_at = None
    stopping = False
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
            if cell.coach is not None and cell.coach.feed(line) is not None and not stopping:
                # The attack is over: the field stays FINISHED, the launch is stopped.
                stopping = True
                launch.send_signal(signal.SIGINT)
            # The fall: the robot knocked over a moment after it starts walking.
            if (cell.phase == "fall" and knock_at is None
                    and COACH_PHASES["go_to"] in line):
                knock_at = time.monotonic() + 1.5
            if cell.killed_at is None and trigger in line and cell.component in cell.pids:
                try:
                    os.kill(cell.pids[cell.component], signal.SIGKILL)
                    cell.killed_at = line.strip()
                    cell.killed_line = seen
                except ProcessLookupError:
                    pass
        if knock_at is not None and time.monotonic() >= knock_at and "spl_field" in cell.pids:
            knock_at = float("inf")
            try:
                os.kill(cell.pids["spl_field"], signal.SIGUSR1)
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
        if stopping and cell.exit in (-signal.SIGINT, 130):
            cell.exit = 0
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
    # A component killed as the game ends is not restarted when the graph is done before the
    # restart's back-off is over: no fault of the graph.
    done_after_kill = cell.killed_line is not None and any(
        "the graph is done" in l for l in cell.lines[cell.killed_line:])
    if cell.killed_at is not None and not done_after_kill and not any(
            f"{cell.component} stopped" in l and "restart 1/" in l for l in cell.lines):
        why.append("not restarted")
    if cell.game == "touch":
        again = [l for l in cell.lines if "says it again" in l]
        if again:
            why.append(f"the person repeated a command {len(again)}x: "
                       + again[0].split("person: ", 1)[-1])
        untrue = [s for s in cell.said if any(u.lower() in s.lower() for u in UNTRUE)]
    else:
        coach = cell.coach
        if coach.attack == 0:
            why.append("PLAYING never came")
        for k in range(1, coach.attack + 1):
            for w in coach.verdict(k):
                why.append(f"the coach's {w}")
        given = {b for k in coach.given for _, b in coach.given[k]}
        stray = sorted({b for k in coach.obeyed for _, b in coach.obeyed[k]} - given)
        if stray:
            why.append("the robot obeyed commands the coach never gave: " + ", ".join(stray))
        untrue = [s for s in cell.said
                  if any(u.lower() in s.lower() and phase != cell.phase
                         for u, phase in COACH_UNTRUE.items())]
    if untrue:
        why.append("the robot said: " + "; ".join(f'"{s}"' for s in untrue))
    return why


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("bin_dir")
    ap.add_argument("out_dir")
    ap.add_argument("--game", choices=["touch", "coach"], default="touch")
    a, rest = ap.parse_known_args()
    components, phases = ((COMPONENTS, PHASES) if a.game == "touch"
                          else (COACH_COMPONENTS, COACH_PHASES))
    ap.add_argument("--components", default=",".join(components))
    ap.add_argument("--phases", default=",".join(phases))
    a = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    comps = [c for c in a.components.split(",") if c]
    chosen = [p for p in a.phases.split(",") if p]
    for p in chosen:
        if p not in phases:
            sys.exit(f"unknown phase {p!r} of the {a.game} game: the phases are "
                     f"{', '.join(phases)}")
    for c in comps:
        if c not in components:
            sys.exit(f"unknown component {c!r} of the {a.game} game: the components are "
                     f"{', '.join(components)}")
    os.makedirs(a.out_dir, exist_ok=True)
    started = time.monotonic()
    results = {}
    total = len(comps) * len(chosen)
    n = 0
    for c in comps:
        for p in chosen:
            n += 1
            cell = Cell(a.game, c, p)
            run_cell(a.bin_dir, root, a.out_dir, n, cell)
            why = verdict(cell)
            results[(c, p)] = why
            mins = (time.monotonic() - started) / 60
            print(f"  cell {n} of {total}: {c} killed at {p}: "
                  f"{'passed' if not why else 'FAILED: ' + ' | '.join(why)} ({mins:.0f} min)",
                  file=sys.stderr, flush=True)

    print()
    what = ("the touch game (scenario still)" if a.game == "touch"
            else f"the coach game (one attack at {COACH_SCALE:g}x, four panel commands)")
    print(f"chaos matrix: {what}, each component killed (SIGKILL) as each phase begins; "
          f"{os.cpu_count()} cores")
    print(f"{'component':24} " + " ".join(f"{p:>9}" for p in chosen))
    for c in comps:
        print(f"{c:24} " + " ".join(f"{'ok' if not results[(c, p)] else 'FAIL':>9}"
                                    for p in chosen))
    failed = {k: v for k, v in results.items() if v}
    if failed:
        print("\nfailed cells:")
        for (c, p), why in failed.items():
            print(f"  {c} at {p}: " + " | ".join(why))
    print(f"\nevery cell's output: {a.out_dir}")
    print(json.dumps({
        "game": a.game,
        "cells": total,
        "cells_passed": total - len(failed),
        "cells_failed": len(failed),
        "repeated_commands": sum(1 for v in failed.values() for w in v
                                 if "repeated" in w or "never reached" in w),
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

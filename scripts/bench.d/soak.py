#!/usr/bin/env python3
"""The soak's sampler (scripts/bench soak): runs one `robocog launch` that plays a game GAMES
times, and after each game samples every process of the graph (the launcher, its router and
each component): resident memory, open file descriptors, threads, and the router's sessions
(established TCP connections of the router). Writes one CSV row per process per game, prints a
table of each resource at game WARM and at the last game, and as its last line one JSON object
with the figures.

The touch game is played by the simulated person (a game that fails stops the launch). The
coach game's attacks are played by `sim_coach.Coach` from outside the graph, which judges
each attack; the launch is stopped after the last.

Growth is compared between means over a few games (WINDOW) around game WARM and at the end, so
that one game's allocator noise is not taken for a leak.

Usage: soak.py LAUNCH_ARGS_FILE CSV GAMES WARM [--coach ROBOCOG NAMESPACE TIME_SCALE]
"""
import csv
import json
import os
import re
import signal
import subprocess
import sys
import time

WINDOW = 5
TARGET_PCT = 5.0
GAME_DONE = re.compile(r'completed \(game (\d+) of (\d+)\)')


def children(pid):
    """The pids whose parent is `pid`, from /proc: the launcher's components and its router
    (not their own short-lived helpers, such as an espeak-ng run)."""
    parent = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                stat = f.read()
            ppid = int(stat[stat.rindex(")") + 2:].split()[1])
            parent.setdefault(ppid, []).append(int(d))
        except (OSError, ValueError):
            continue
    return parent.get(pid, [])


def name_of(pid):
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            argv = [a.decode(errors="replace") for a in f.read().split(b"\0")]
        name = os.path.basename(argv[0]) or "?"
        # The machine's router is `robocog router`, a child of the launcher.
        return "router" if name == "robocog" and argv[1:2] == ["router"] else name
    except OSError:
        return None


def sample(pid):
    """(rss_kib, fds, threads, socket inodes) of one process, or None if it is gone."""
    try:
        with open(f"/proc/{pid}/status") as f:
            status = f.read()
        rss = int(re.search(r"^VmRSS:\s+(\d+)", status, re.M).group(1))
        threads = int(re.search(r"^Threads:\s+(\d+)", status, re.M).group(1))
        inodes = set()
        fds = 0
        for fd in os.listdir(f"/proc/{pid}/fd"):
            fds += 1
            try:
                link = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            if link.startswith("socket:["):
                inodes.add(link[8:-1])
        return rss, fds, threads, inodes
    except (OSError, AttributeError):
        return None


def established(inodes):
    """How many of these sockets are established TCP connections."""
    n = 0
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            with open(table) as f:
                next(f)
                for line in f:
                    cols = line.split()
                    if cols[3] == "01" and cols[9] in inodes:
                        n += 1
        except OSError:
            continue
    return n


def main():
    args_file, csv_path, games, warm = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    coach = None
    if sys.argv[5:6] == ["--coach"]:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        from sim_coach import Coach
        coach = Coach(sys.argv[6], sys.argv[7], float(sys.argv[8]))
    game_name = "touch game" if coach is None else "coach game's attack"
    failed = {}  # game -> what went wrong (the coach's attacks)
    with open(args_file) as f:
        launch = [line.rstrip("\n") for line in f if line.strip()]
    log_path = csv_path[: -len(".csv")] + ".log"
    log = open(log_path, "w")
    proc = subprocess.Popen(launch, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            bufsize=1)
    rows = []  # (game, process, pid, rss_kib, fds, threads)
    sessions = {}  # game -> router sessions
    started = time.monotonic()
    played = 0
    for line in proc.stdout:
        log.write(line)
        if coach is None:
            m = GAME_DONE.search(line)
            game = int(m.group(1)) if m else None
        else:
            game = coach.feed(line)
        if game is None:
            continue
        played = game
        if coach is not None:
            why = coach.verdict(game)
            if why:
                failed[game] = why
                print(f"  attack {game} FAILED: {' | '.join(why)}", file=sys.stderr, flush=True)
        seen = {}
        router_seen = False
        for pid in [proc.pid] + children(proc.pid):
            name = "launcher" if pid == proc.pid else name_of(pid)
            s = sample(pid)
            if name is None or s is None:
                continue
            k = seen.get(name, 0)
            seen[name] = k + 1
            if k:
                name = f"{name}#{k + 1}"
            rows.append((game, name, pid, s[0], s[1], s[2]))
            # The router's sessions (a launcher that hosts its router in-process: its own).
            if name == "router" or (pid == proc.pid and not router_seen):
                sessions[game] = established(s[3])
                router_seen |= name == "router"
        if game == 1 or game % 10 == 0 or game == games:
            mins = (time.monotonic() - started) / 60
            print(f"  game {game} of {games} played, {game - len(failed)} passed "
                  f"({mins:.1f} min)", file=sys.stderr, flush=True)
        if coach is not None and game == games:
            # The field stays FINISHED after its last attack: the launch is stopped.
            proc.send_signal(signal.SIGINT)
    rc = proc.wait()
    rc = 0 if coach is not None and played == games and rc in (0, -signal.SIGINT, 130) else rc
    passed = played - len(failed)
    log.close()

    with open(csv_path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["game", "process", "pid", "rss_kib", "fds", "threads", "router_sessions"])
        for r in rows:
            w.writerow(list(r) + [sessions.get(r[0], "")])

    if rc != 0 or played < games:
        print(f"the soak stopped after {played} of {games} games (launcher exit {rc}); "
              f"its log: {log_path}", file=sys.stderr)
        with open(log_path) as f:
            sys.stderr.writelines(f.readlines()[-30:])

    # Means over WINDOW games from game WARM, and over the last WINDOW games played.
    # The last game's sample races with the graph's shutdown (the person leaves, the launcher
    # stops everything): it is left out of the means.
    last = max(played - 1, 1) if played == games else max(played, 1)
    warm = max(1, min(warm, last - 1))
    window = max(1, min(WINDOW, (last - warm + 1) // 2))
    early = set(range(warm, warm + window))
    late = set(range(last - window + 1, last + 1))
    names = sorted({r[1] for r in rows}, key=lambda n: (n not in ("launcher", "router"), n))

    def mean(values):
        return sum(values) / len(values) if values else float("nan")

    def growth(a, b):
        return (b - a) / a * 100 if a > 0 else 0.0

    worst = {"rss": (0.0, ""), "fds": (0.0, ""), "threads": (0.0, "")}
    restarts_total = 0
    print()
    print(f"soak: the {game_name} played {played} of {games} times in one launch, {passed} "
          f"passed, "
          f"{os.cpu_count()} cores; means over games {min(early)}-{max(early)} and "
          f"{min(late)}-{last}")
    print(f"{'process':28} {'restarts':>8} {'RSS MiB':>16} {'growth':>7} {'fds':>11} "
          f"{'growth':>7} {'threads':>9} {'growth':>7}")
    for name in names:
        mine = [r for r in rows if r[1] == name]
        restarts = len({r[2] for r in mine}) - 1
        restarts_total += restarts
        cols = []
        for key, idx in (("rss", 3), ("fds", 4), ("threads", 5)):
            a = mean([r[idx] for r in mine if r[0] in early])
            b = mean([r[idx] for r in mine if r[0] in late])
            g = growth(a, b)
            if restarts == 0 and g > worst[key][0]:
                worst[key] = (g, name)
            cols.append((a, b, g))
        (ra, rb, rg), (fa, fb, fg), (ta, tb, tg) = cols
        print(f"{name:28} {restarts:8d} {ra / 1024:7.1f} -> {rb / 1024:6.1f} {rg:6.1f}% "
              f"{fa:4.0f} -> {fb:4.0f} {fg:6.1f}% {ta:3.0f} -> {tb:3.0f} {tg:6.1f}%")
    s_early = mean([sessions[g] for g in early if g in sessions])
    s_late = mean([sessions[g] for g in late if g in sessions])
    print(f"router sessions (established TCP): {s_early:.1f} -> {s_late:.1f}")
    if coach is not None:
        print(f"the field's own time: {coach.field_s / 60:.1f} min")
    if failed:
        print(f"failed: " + "; ".join(f"{g}: {' | '.join(w)}" for g, w in sorted(failed.items())))
    ok = passed == games and all(w[0] <= TARGET_PCT for w in worst.values()) \
        and s_late <= s_early and restarts_total == 0
    print(f"target: every game passes and nothing grows more than {TARGET_PCT:.0f} % "
          f"between game {warm} and the end: {'met' if ok else 'NOT met'}")
    print(f"per game and process: {csv_path}")
    print(json.dumps({
        "games": games,
        "games_played": played,
        "games_passed": passed,
        "minutes": round((time.monotonic() - started) / 60, 1),
        "rss_growth_max_pct": round(worst["rss"][0], 2),
        "rss_growth_max_process": worst["rss"][1],
        "fds_growth_max_pct": round(worst["fds"][0], 2),
        "threads_growth_max_pct": round(worst["threads"][0], 2),
        "restarts": restarts_total,
        "router_sessions_early": round(s_early, 1),
        "router_sessions_late": round(s_late, 1),
        "target_met": ok,
        **({} if coach is None else {"field_minutes": round(coach.field_s / 60, 1)}),
    }))
    # A failed game or a growth is a figure of the soak (target_met), not a failure of the benchmark.
    sys.exit(0)


if __name__ == "__main__":
    main()

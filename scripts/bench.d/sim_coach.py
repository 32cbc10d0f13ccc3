"""A coach at the simulated SPL field, for the benchmarks that play the coach game from outside
(scripts/bench soak coach, scripts/bench chaos coach): it reads the launcher's output, and in
every attack's PLAYING gives the controlled robot a plan of commands from the panel's topic
(`coach/request`, through `robocog topic pub`), over and over until the attack ends, as an
operator clicking the panel would.

A command counts as carried out when the simulated robot obeys a command packet after it was
given and before the next one is given (or the attack ends): the field logs every packet it
obeys ("robot 2 obeys ..."). A fall or a penalty only delays that: the Executive keeps the
command and sends it when the robot can act.
"""
import itertools
import json
import re
import subprocess
import threading
import time

# The plan of every attack, given again and again until the attack ends: (simulated seconds
# after the previous command, body, target).
PLAN = [
    (1.0, "GoToPosition", (-500.0, -1500.0)),
    (12.0, "Turn", (4500.0, 0.0)),
    (6.0, "SearchTheBall", None),
    (8.0, "GoToBallAndDribble", None),
]
PLAYING = "StateChanged { state: Playing }"
OBEYS = re.compile(r"robot 2 obeys Some\((\w+)\)")
ATTACK_DONE = re.compile(r"attack (\d+) of (\d+) finished")
ROUTER = re.compile(r"router (tcp/[0-9.]+:\d+)")
FIELD_TIME = re.compile(r"spl_field \|.* t=(\d+(?:\.\d+)?)s ")


def request(body, target):
    command = {"body": body, "source": "panel"}
    if target is not None:
        command["target"] = {"x_mm": target[0], "y_mm": target[1]}
    return json.dumps({"command": command})


class Coach:
    """Feed it every line of the launcher's output; it gives each attack's plan and judges it."""

    def __init__(self, robocog, namespace, time_scale, plan=PLAN):
        self.robocog, self.ns, self.scale, self.plan = robocog, namespace, time_scale, plan
        self.router = None
        self.lock = threading.Lock()
        self.attack = 0
        self.given = {}    # attack -> [(monotonic time, body)]
        self.obeyed = {}   # attack -> [(monotonic time, body)]
        self.errors = {}   # attack -> [what went wrong giving a command]
        self.over = threading.Event()
        self.field_s = 0.0  # the field's simulated time at its last event

    def feed(self, line):
        """One line of the launcher's output. Returns the attack number when one finished."""
        m = FIELD_TIME.search(line)
        if m:
            self.field_s = max(self.field_s, float(m.group(1)))
        m = ROUTER.search(line)
        if m and self.router is None:
            self.router = m.group(1)
        if PLAYING in line:
            with self.lock:
                self.attack += 1
                self.over = threading.Event()
                k, over = self.attack, self.over
            threading.Thread(target=self.play, args=(k, over), daemon=True).start()
            return None
        m = OBEYS.search(line)
        if m:
            with self.lock:
                self.obeyed.setdefault(self.attack, []).append((time.monotonic(), m.group(1)))
            return None
        m = ATTACK_DONE.search(line)
        if m:
            self.over.set()
            return int(m.group(1))
        return None

    def give(self, body, target):
        """Publishes one panel request; returns what went wrong, or None."""
        if self.router is None:
            return "no router address seen in the launcher's output"
        try:
            r = subprocess.run(
                [self.robocog, "topic", "pub", "coach/request", request(body, target),
                 "--type", "robocog.nao.CoachRequest", "--wait", "20",
                 "--namespace", self.ns, "--connect", self.router],
                capture_output=True, text=True, timeout=40)
        except subprocess.TimeoutExpired:
            return f"{body}: robocog topic pub timed out"
        if r.returncode != 0:
            return f"{body}: robocog topic pub failed: {r.stderr.strip()[-200:]}"
        if "publishing anyway" in r.stderr:
            return f"{body}: nobody subscribed to coach/request for 20 s (the Executive?)"
        return None

    def play(self, k, over):
        for after_s, body, target in itertools.cycle(self.plan):
            if over.wait(after_s / self.scale):
                return
            at = time.monotonic()
            err = self.give(body, target)
            with self.lock:
                self.given.setdefault(k, []).append((at, body))
                if err:
                    self.errors.setdefault(k, []).append(err)

    def verdict(self, k):
        """What went wrong in attack `k` (nothing: every command given was carried out)."""
        with self.lock:
            given = list(self.given.get(k, []))
            obeyed = list(self.obeyed.get(k, []))
            why = list(self.errors.get(k, []))
        for i, (at, body) in enumerate(given):
            until = given[i + 1][0] if i + 1 < len(given) else float("inf")
            if not any(at <= t < until for t, _ in obeyed):
                why.append(f"{body} (command {i + 1}) never reached the robot")
        return why

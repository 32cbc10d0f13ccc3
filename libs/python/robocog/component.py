"""A Python component, run like a Rust one: its own flags beside the shared ones, `--help`,
`--describe` (its topics and services as JSON, for `robocog check`), `--preflight`, exit codes
the launcher reads (78: a configuration error a restart would not fix; 64: bad flags).

    class Tracker(Component):
        NAME = "ball_tracker"
        ABOUT = "finds the ball in the RGB-D frames"
        SUBSCRIBES = [("vision/rgbd", msg.RgbdFrame)]
        PUBLISHES = [("vision/ball", msg.BallTrack)]

        @classmethod
        def add_arguments(cls, parser):
            parser.add_argument("--hue", type=float, default=0.0)

        def __init__(self, node, args):
            self.out = node.publisher("vision/ball", msg.BallTrack)
            node.subscribe("vision/rgbd", msg.RgbdFrame, self.on_frame)

    if __name__ == "__main__":
        sys.exit(robocog.component.main(Tracker))
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import json
import logging
import os
import sys
from typing import Any

from . import Node, _robocog, type_name

#: A configuration error: the launcher does not restart the component.
EX_CONFIG = 78
#: Bad flags.
EX_USAGE = 64


class ConfigError(Exception):
    """Raised by `Component.prepare` when the flags or files cannot work: the component exits
    78 before it joins the bus, and is not restarted."""


class Component:
    """Subclass it, declare the interface, and run it with `main`."""

    NAME: str = ""
    ABOUT: str = ""
    #: (topic, message class or type name)
    PUBLISHES: list[tuple[str, Any]] = []
    SUBSCRIBES: list[tuple[str, Any]] = []
    #: (service, request class, reply class)
    SERVES: list[tuple[str, Any, Any]] = []
    CALLS: list[tuple[str, Any, Any]] = []
    #: Hardware it claims (`udp:65305`, `serial:/dev/ttyUSB0`).
    HARDWARE: list[str] = []
    #: "log": a callback that raises is logged and counted, and the component goes on;
    #: "exit": it exits 1 (the launcher restarts it by its policy).
    ON_ERROR: str = "log"

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        """Add the component's own flags."""

    @classmethod
    def prepare(cls, args: argparse.Namespace) -> Any:
        """Check the flags and do the slow setup (read files, load models) before joining the
        bus; raise `ConfigError` for what a restart cannot fix. Returns what `__init__` gets."""
        return args

    def __init__(self, node: Node, prepared: Any) -> None:
        self.node = node

    def close(self) -> None:
        """Called once `spin` returns (asked to stop)."""

    @classmethod
    def interface(cls, args: argparse.Namespace | None = None) -> dict[str, Any]:
        """What `--describe` prints (the Rust components' format), for the parsed flags `args`:
        override it when flags change the topics (a `--no-dr` that calls no `dr/*`)."""

        def ports(entries: list[tuple[Any, ...]]) -> list[dict[str, str]]:
            return [{"name": e[0], "type_name": type_name(e[1])} for e in entries]

        return {
            "component": cls.NAME,
            "publishes": ports(cls.PUBLISHES),
            "subscribes": ports(cls.SUBSCRIBES),
            "serves": ports(cls.SERVES),
            "calls": ports(cls.CALLS),
            "hardware": list(cls.HARDWARE),
        }


class _RustLikeFormatter(logging.Formatter):
    """Log lines as the Rust components write them: UTC time, level, message."""

    LEVELS = {"WARNING": "WARN", "CRITICAL": "ERROR"}

    def format(self, record: logging.LogRecord) -> str:
        record.levelname = self.LEVELS.get(record.levelname, record.levelname)
        return super().format(record)

    def formatTime(self, record: logging.LogRecord, datefmt: str | None = None) -> str:
        import datetime

        t = datetime.datetime.fromtimestamp(record.created, datetime.timezone.utc)
        return t.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _setup_logging() -> None:
    """Python's `logging` to stderr, at `ROBOCOG_PY_LOG` (default INFO)."""
    level = os.environ.get("ROBOCOG_PY_LOG", "INFO").upper()
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_RustLikeFormatter("%(asctime)s %(levelname)5s %(message)s"))
    logging.basicConfig(level=getattr(logging, level, logging.INFO), handlers=[handler])


def main(cls: type[Component], argv: list[str] | None = None) -> int:
    """Parse the flags, then describe, preflight or run `cls` until SIGTERM. Returns the exit
    code."""
    if not cls.NAME:
        raise TypeError(f"{cls.__name__} has no NAME")
    parser = argparse.ArgumentParser(
        prog=cls.NAME,
        description=cls.ABOUT,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Flags every component accepts (robocog's runtime):\n\n"
        + _robocog.node_flags_help().split("Options:", 1)[-1],
    )
    parser.add_argument(
        "--describe", action="store_true", help="print the topics and services as JSON, exit"
    )
    parser.add_argument(
        "--preflight",
        action="store_true",
        help="check the configuration as a start would, say so, exit (0, or 78 and the reason)",
    )
    cls.add_arguments(parser)
    args, rest = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    if args.describe:
        print(json.dumps(cls.interface(args), indent=2))
        return 0
    _setup_logging()
    name = os.environ.get("ROBOCOG_COMPONENT", cls.NAME)
    try:
        prepared = cls.prepare(args)
    except ConfigError as e:
        if args.preflight:
            print(f"{name}: cannot start: {e}", file=sys.stderr)
        else:
            print(
                f"{name}: cannot start: {e} (a configuration error: exit {EX_CONFIG}, "
                "a restart would not fix it)",
                file=sys.stderr,
            )
        return EX_CONFIG
    if args.preflight:
        print(f"{name}: ready to start")
        return 0
    try:
        node = Node(cls.NAME, rest, serves=[s[0] for s in cls.SERVES], on_error=cls.ON_ERROR)
    except ValueError as e:
        # The shared flags did not parse: clap's message names the flag.
        print(str(e).rstrip(), file=sys.stderr)
        return EX_USAGE
    component = cls(node, prepared)
    try:
        node.spin()
    except KeyboardInterrupt:
        node.log.info("interrupted: stopping")
    finally:
        component.close()
    return 0


def load(spec: str) -> type[Component]:
    """The component class `MODULE[:CLASS]` names (without CLASS: the module's one Component
    subclass)."""
    module_name, _, class_name = spec.partition(":")
    module = importlib.import_module(module_name)
    if class_name:
        cls = getattr(module, class_name, None)
        if not (inspect.isclass(cls) and issubclass(cls, Component)):
            raise LookupError(f"{module_name} has no Component subclass named {class_name}")
        return cls
    # The Component subclasses the module holds, defined there or imported into it.
    found = [
        c
        for c in vars(module).values()
        if inspect.isclass(c) and issubclass(c, Component) and c is not Component
    ]
    if len(found) != 1:
        names = ", ".join(c.__name__ for c in found) or "none"
        raise LookupError(
            f"{module_name} defines {len(found)} Component subclasses ({names}): name one as "
            f"{module_name}:CLASS"
        )
    return found[0]


def run_named(spec: str, argv: list[str]) -> int:
    """Load the component `spec` names and run it (`python -m robocog run SPEC ...`)."""
    try:
        cls = load(spec)
    except (ImportError, LookupError) as e:
        print(f"robocog: cannot load the component {spec}: {e}", file=sys.stderr)
        return EX_CONFIG
    return main(cls, argv)

"""A small step-by-step debugger, in the spirit of FlowDesigner's."""
from __future__ import annotations

import shlex
from typing import Callable, TextIO

from .errors import SemmapError
from .runner import Runner

HELP = """commands:
  step [N]        run N ticks (default 1)            (alias: s)
  run N           same as step N
  print NODE.PORT show a port's current value        (alias: p)
  watch NODE.PORT print this port after every step   (alias: w)
  nodes           list the schedule
  tick            show the current tick
  reset           back to tick 0
  quit            leave                              (alias: q)"""


class Debugger:
    """Read commands, step the runner, print ports."""

    def __init__(self, runner: Runner, read: Callable[[str], str] = input,
                 out: TextIO | None = None) -> None:
        import sys
        self.runner = runner
        self.read = read
        self.out = out or sys.stdout
        self.watches: list[str] = []

    def say(self, text: str) -> None:
        print(text, file=self.out)

    def loop(self) -> None:
        self.say(f"semmap debug: {self.runner.graph.name}, tick 0. Type 'help'.")
        while True:
            try:
                line = self.read("(semmap) ")
            except EOFError:
                return
            if not self.handle(line):
                return

    def handle(self, line: str) -> bool:
        """Run one command; False means quit."""
        try:
            words = shlex.split(line)
        except ValueError as exc:
            self.say(f"cannot parse: {exc}")
            return True
        if not words:
            return True
        cmd, args = words[0], words[1:]
        try:
            if cmd in ("q", "quit", "exit"):
                return False
            if cmd in ("s", "step", "run"):
                n = int(args[0]) if args else 1
                status = self.runner.run(n)
                self.say(f"tick {self.runner.tick} ({status})")
                for name in self.watches:
                    self.say(f"  {name} = {self.runner.value(name)!r}")
            elif cmd in ("p", "print"):
                for name in args:
                    self.say(f"{name} = {self.runner.value(name)!r}")
            elif cmd in ("w", "watch"):
                for name in args:
                    self.runner.value(name)  # validates the name
                    self.watches.append(name)
            elif cmd == "nodes":
                for task in self.runner.tasks:
                    self.say(f"  {task.node} [{task.phase}]")
            elif cmd == "tick":
                self.say(f"tick {self.runner.tick}")
            elif cmd == "reset":
                self.runner.reset()
                self.say("tick 0")
            elif cmd in ("h", "help", "?"):
                self.say(HELP)
            else:
                self.say(f"unknown command {cmd!r}; type 'help'")
        except (SemmapError, ValueError) as exc:
            self.say(f"error: {exc}")
        return True

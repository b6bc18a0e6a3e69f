"""One line on standard error when numba compiles algid's kernels for more than a second.

The compiled kernels (the tracker's recurrences and solves, the estimator's loops, the
checks of the signals) are compiled by numba at their first call and cached on disk:
on a fresh installation the first call waits ten to twenty seconds, and would otherwise wait
in silence.  :func:`watch` installs a listener of numba's compile events: when one of
algid's functions has been compiling for :data:`DELAY` seconds, it says so, once per
process.  Loading machine code from numba's cache raises no compile event: nothing is
said then.
"""

from __future__ import annotations

import sys
import threading

__all__ = ["DELAY", "watch", "said", "mark_said"]

#: Seconds of compiling before the line is printed.
DELAY = 1.0

_lock = threading.Lock()
_state = {"installed": False, "said": False, "depth": 0, "timer": None}


def said():
    """Whether the line was printed in this process.

    Returns
    -------
    bool
    """
    return _state["said"]


def mark_said():
    """Record that the compilation was announced another way (no second line)."""
    _state["said"] = True


def _say(name):
    with _lock:
        if _state["said"]:
            return
        _state["said"] = True
    print(f"algid: numba is compiling {name} and the kernels it calls, at their first use "
          f"on this installation; this takes ten to twenty seconds once (the machine code is "
          f"cached for the next runs)", file=sys.stderr, flush=True)


def _ours(event):
    function = getattr((event.data or {}).get("dispatcher"), "py_func", None)
    module = getattr(function, "__module__", "") or ""
    return module.startswith("algid"), getattr(function, "__qualname__", "a kernel")


def watch():
    """Install the listener (once per process; numba is imported here).

    Returns
    -------
    None
    """
    if _state["installed"]:
        return
    from numba.core import event

    class _Listener(event.Listener):
        def on_start(self, ev):
            ours, name = _ours(ev)
            if not ours:
                return
            with _lock:
                _state["depth"] += 1
                if _state["depth"] == 1 and not _state["said"]:
                    timer = threading.Timer(DELAY, _say, args=(name,))
                    timer.daemon = True
                    _state["timer"] = timer
                    timer.start()

        def on_end(self, ev):
            if not _ours(ev)[0]:
                return
            with _lock:
                _state["depth"] -= 1
                if _state["depth"] == 0 and _state["timer"] is not None:
                    _state["timer"].cancel()
                    _state["timer"] = None

    with _lock:
        if not _state["installed"]:
            event.register("numba:compile", _Listener())
            _state["installed"] = True

"""Sizes checked against the memory available, before anything is allocated.

A request that cannot fit (a simulation of ``10**10`` samples, a data file larger than
the memory) is refused with an :class:`~algid.errors.InputDataError` that gives the
numbers, instead of ending in a ``MemoryError`` or in swapping.  The memory available
is read from the operating system (``MemAvailable`` of ``/proc/meminfo`` on Linux,
else the free physical pages); where it cannot be read, :data:`FALLBACK_MEMORY_BYTES`
is assumed.  A limit on the process's address space (``ulimit -v``) lowers it to what
the limit leaves.
"""

from __future__ import annotations

import os

from algid.errors import InputDataError

__all__ = ["available_memory", "check_fits", "FALLBACK_MEMORY_BYTES"]

#: Memory assumed available [bytes] where the operating system does not say: 8 GiB.
FALLBACK_MEMORY_BYTES = 8 * 2**30


def _address_space_left():
    """What the process's address-space limit leaves [bytes], or None without one."""
    try:
        import resource

        limit = resource.getrlimit(resource.RLIMIT_AS)[0]
        if limit == resource.RLIM_INFINITY:
            return None
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmSize:"):
                    return max(0, limit - int(line.split()[1]) * 1024)
    except (ImportError, OSError, ValueError, IndexError):
        pass
    return None


def available_memory() -> int:
    """Memory available to a new allocation without swapping [bytes].

    Returns
    -------
    int
        ``MemAvailable`` from ``/proc/meminfo`` (Linux), else the free physical pages
        (``os.sysconf``), else :data:`FALLBACK_MEMORY_BYTES`; at most what an
        address-space limit (``ulimit -v``) leaves.
    """
    left = _address_space_left()
    physical = _physical_memory()
    return physical if left is None else min(physical, left)


def _physical_memory() -> int:
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):
        return FALLBACK_MEMORY_BYTES


def _size(n_bytes) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.3g} {unit}"
    return f"{n_bytes / 1e3:.3g} kB"


def check_fits(count, bytes_each, *, what, unit="samples"):
    """Refuse ``count`` items of ``bytes_each`` bytes if they exceed the memory available.

    Parameters
    ----------
    count : int or float
        Number of items (samples, bytes of a file).
    bytes_each : float
        Peak memory needed per item [bytes], measured for the operation.
    what : str
        What is being sized, for the message (e.g. ``"simulate"``, a file name).
    unit : str, optional
        Name of the items, for the message.

    Raises
    ------
    InputDataError
        If ``count * bytes_each`` exceeds :func:`available_memory`; the message gives the
        count, the memory needed and the largest count that fits.
    """
    available = available_memory()
    needed = float(count) * float(bytes_each)
    if needed > available:
        largest = int(available // bytes_each)
        raise InputDataError(
            f"{what}: {float(count):.4g} {unit} need about {_size(needed)} of memory, "
            f"{_size(available)} is available (at most about {largest:.3g} {unit})")

"""Two measured benchmark records, shipped with the package: Silverbox and EMPS.

In the manner of :mod:`scipy.datasets`, each loader returns the record as arrays, read
from files installed with the package (``algid/data/``), so that it works offline from
a plain clone or an installed wheel.  The files are the originals as distributed by the
nonlinear system identification benchmark community (the Silverbox CSV gzip-compressed,
byte for byte); ``algid/data/README.md`` records their provenance and checksums.

Silverbox
    An electronic circuit that behaves as a mass-spring-damper with a hardening cubic
    spring, ``m y'' + d y' + a y + b y**3 = u``, measured at VUB (Brussels) in 1999.
    ``V1`` is the input voltage, ``V2`` the output voltage, sampled at 610.35 Hz.
    Cite: T. Wigren, J. Schoukens, "Three free data sets for development and
    benchmarking in nonlinear system identification", European Control Conference
    (ECC), 2013.

EMPS
    An electro-mechanical positioning system (a mass on a ball screw driven by a DC
    motor, no spring), recorded at 1 kHz in closed loop under a position controller.
    ``qm`` is the measured position [m], ``vir`` the drive command [V], the force on
    the mass ``F = gtau * vir`` [N], ``qg`` the reference position [m].  The validation
    run has force pulses injected into the drive command; ``vir`` already carries them
    (see :func:`emps`).  Published reference model
    (inverse-model least squares): ``M*q'' + Fv*q' + Fc*sign(q') + off = F`` with
    M = 95.1089 kg, Fv = 203.5034 N s/m, Fc = 20.3935 N, off = -3.1648 N
    (:data:`EMPS_PUBLISHED`, keyed by these parameter names).
    Cite: A. Janot, M. Gautier, M. Brunot, "Data Set and Reference Models of EMPS",
    Workshop on Nonlinear System Identification Benchmarks, 2019.

:func:`export` (and ``algid datasets export NAME DIR`` on the command line) writes the
records as plain CSV files with a time column ``t``, which ``algid identify`` reads as
they are.

Neither data set states a licence of its own; both are distributed freely by the
benchmark community, which asks users to cite the papers above.
"""

from __future__ import annotations

import contextlib
import functools
import gzip
import io
import os
import stat
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from algid.errors import AlgidError, InputDataError

__all__ = ["BenchmarkRecord", "silverbox", "emps", "EMPS_EQUATION", "EMPS_PUBLISHED",
           "EMPS_PUBLISHED_RELATIVE_STD", "EMPS_PUBLISHED_FORCE_ERROR", "SILVERBOX_FILE",
           "EMPS_FILES", "export", "EXPORTS"]

SILVERBOX_FILE = "SNLS80mV.csv.gz"
EMPS_FILES = {"estimation": "DATA_EMPS.mat", "validation": "DATA_EMPS_PULSES.mat"}

SILVERBOX_CITATION = (
    'T. Wigren, J. Schoukens, "Three free data sets for development and benchmarking '
    'in nonlinear system identification", European Control Conference (ECC), 2013.')
EMPS_CITATION = (
    'A. Janot, M. Gautier, M. Brunot, "Data Set and Reference Models of EMPS", '
    'Workshop on Nonlinear System Identification Benchmarks, 2019.')

#: The published reference model of the EMPS, as :func:`algid.identify` reads it, in the
#: names of the record's columns: ``identify(emps(), EMPS_EQUATION, list(EMPS_PUBLISHED))``.
EMPS_EQUATION = "M*qm'' + Fv*qm' + Fc*sign(qm') + off = F"

#: Published IDIM-LS values (Janot et al. 2019) of the parameters of
#: :data:`EMPS_EQUATION`, exactly its parameters: pass it wherever parameter values of
#: that model are expected (``result.with_parameters(EMPS_PUBLISHED)``).
EMPS_PUBLISHED = {"M": 95.1089, "Fv": 203.5034, "Fc": 20.3935, "off": -3.1648}

#: Relative standard deviations of the published values, per parameter.
EMPS_PUBLISHED_RELATIVE_STD = {"M": 0.0011, "Fv": 0.0056, "Fc": 0.0050, "off": 0.014}

#: Published relative error of the force predicted by the published model, per run.
EMPS_PUBLISHED_FORCE_ERROR = {"estimation": 0.0408, "validation": 0.0598}

# Silverbox: 0-based, half-open row ranges of the record's parts.
SILVERBOX_SEGMENTS = {
    "arrow": (100, 40575),         # filtered Gaussian noise, amplitude growing linearly
    "estimation": (40650, 105712),  # odd random-phase multisines (usual training part)
    "test": (105712, 127400),       # more multisines (usual test part)
}
SILVERBOX_RATE = 610.35  # Hz


@dataclass(frozen=True, eq=False)
class BenchmarkRecord(Mapping):
    """One measured record: a mapping of signal name to samples, with its metadata.

    The record behaves as a read-only ``dict`` of its sampled signals (``rec["V1"]``,
    ``list(rec)``), so it can be passed wherever a mapping of column name to samples
    is accepted; signals and constants are also attributes (``rec.V1``, ``rec.gtau``).

    Attributes
    ----------
    name : str
        ``"silverbox"``, ``"emps/estimation"`` or ``"emps/validation"``.
    signals : dict of str to numpy.ndarray
        The sampled signals, 1-D ``float64`` arrays of equal length.
    rate : float
        The (nominal) sampling rate in Hz.
    constants : dict of str to float
        Scalars stored with the record (EMPS: ``gtau``, ``kp``, ``kv``).
    segments : dict of str to (int, int)
        Named parts of the record as 0-based half-open row ranges (Silverbox).
    description : str
        What the signals are, with units.
    citation : str
        The reference to cite when using the record.

    Examples
    --------
    >>> from algid.datasets import emps
    >>> record = emps()
    >>> record
    BenchmarkRecord(name='emps/estimation', signals=[t, qm, vir, qg, F], n_samples=24841,
                    rate=1000.0)
    >>> list(record), record["F"] is record.F
    (['t', 'qm', 'vir', 'qg', 'F'], True)
    """

    name: str
    signals: dict
    rate: float
    constants: dict = field(default_factory=dict)
    segments: dict = field(default_factory=dict)
    description: str = ""
    citation: str = ""

    def __getitem__(self, key):
        return self.signals[key]

    def __iter__(self):
        return iter(self.signals)

    def __len__(self):
        return len(self.signals)

    def __getattr__(self, key):
        # only called when normal lookup fails: expose signals and constants
        for table in ("signals", "constants"):
            values = self.__dict__.get(table, {})
            if key in values:
                return values[key]
        raise AttributeError(f"{type(self).__name__!s} {self.__dict__.get('name')!r} "
                             f"has no signal or constant {key!r}")

    @property
    def fs(self) -> float:
        """The sampling rate in Hz (alias of :attr:`rate`)."""
        return self.rate

    @property
    def n_samples(self) -> int:
        """Number of samples of each signal."""
        return len(next(iter(self.signals.values())))

    def segment(self, name) -> dict:
        """The signals restricted to a named part of the record.

        Parameters
        ----------
        name : str
            One of :attr:`segments` (Silverbox: ``"arrow"``, ``"estimation"``,
            ``"test"``).

        Returns
        -------
        dict of str to numpy.ndarray
            Each signal sliced to the rows of the segment (copies).

        Raises
        ------
        InputDataError
            If the record has no segment of that name.
        """
        if name not in self.segments:
            known = ", ".join(self.segments) or "none"
            raise InputDataError(f"record {self.name!r} has no segment {name!r} "
                                 f"(known: {known})")
        start, stop = self.segments[name]
        return {key: values[start:stop].copy() for key, values in self.signals.items()}

    def __repr__(self):
        names = ", ".join(self.signals)
        return (f"BenchmarkRecord(name={self.name!r}, signals=[{names}], "
                f"n_samples={self.n_samples}, rate={self.rate})")


def _data_file(name):
    return resources.files("algid").joinpath("data", name)


@functools.cache
def _silverbox_arrays():
    with _data_file(SILVERBOX_FILE).open("rb") as raw, gzip.open(raw, "rb") as unzipped:
        text = io.TextIOWrapper(unzipped, encoding="ascii")
        # header "V1","V2", ; every line ends with a trailing comma (an empty 3rd field)
        table = np.loadtxt(text, delimiter=",", skiprows=1, usecols=(0, 1), dtype=np.float64)
    return table[:, 0], table[:, 1]


@functools.cache
def _emps_variables(file_name):
    from scipy.io import loadmat

    with _data_file(file_name).open("rb") as handle:
        contents = loadmat(io.BytesIO(handle.read()))
    return {key: value for key, value in contents.items() if not key.startswith("__")}


def silverbox() -> BenchmarkRecord:
    """The Silverbox benchmark record (Wigren and Schoukens, ECC 2013).

    An electronic circuit that behaves as ``m y'' + d y' + a y + b y**3 = u``: ``V1``
    is the input voltage (the analogue of force), ``V2`` the output voltage (the
    analogue of displacement), 131 072 samples at ``fs = 610.35`` Hz (about 9 samples
    per period of the 68 Hz resonance).  Both channels carry small DC offsets from the
    measurement chain (the input's measured mean is about 6 mV).

    Returns
    -------
    BenchmarkRecord
        Signals ``V1``, ``V2`` [V]; ``rate`` = ``fs`` = 610.35 Hz; ``segments`` (0-based,
        half-open rows): ``"arrow"`` = (100, 40575), filtered Gaussian noise whose
        amplitude grows linearly (rms about 3 mV to 35 mV); ``"estimation"`` =
        (40650, 105712), odd random-phase multisines (the usual training part);
        ``"test"`` = (105712, 127400), more multisines (the usual test part).

    Examples
    --------
    >>> from algid.datasets import silverbox
    >>> sb = silverbox()
    >>> sb.V2.shape, sb.fs
    ((131072,), 610.35)
    >>> arrow = sb.segment("arrow")          # {"V1": ..., "V2": ...}
    """
    v1, v2 = _silverbox_arrays()
    return BenchmarkRecord(
        name="silverbox",
        signals={"V1": v1.copy(), "V2": v2.copy()},
        rate=SILVERBOX_RATE,
        segments=dict(SILVERBOX_SEGMENTS),
        description=("V1: input voltage [V]; V2: output voltage [V]; "
                     "sampled at 610.35 Hz"),
        citation=SILVERBOX_CITATION,
    )


def emps(run="estimation") -> BenchmarkRecord:
    """An EMPS benchmark record (Janot, Gautier and Brunot, 2019).

    An electro-mechanical positioning system (a mass on a ball screw driven by a DC
    motor; no spring) under a position controller, 24 841 samples at 1 kHz.

    Parameters
    ----------
    run : {"estimation", "validation"}
        ``"estimation"``: ``DATA_EMPS.mat``, the run the published model was
        identified on.  ``"validation"``: ``DATA_EMPS_PULSES.mat``, a run with force
        pulses injected into the drive command (``pulses_N``).

    Returns
    -------
    BenchmarkRecord
        Signals: ``t`` time [s] (as stored: steps of 1 ms within a few tens of ns),
        ``qm`` measured position [m] (the output), ``vir`` drive command [V],
        ``qg`` reference position [m], ``F = gtau * vir`` the force on the mass [N];
        the validation run also has ``pulses_N``, the pulse signal stored in the file.
        Constants from the file:
        ``gtau`` [N/V] (drive gain, 35.15), ``kp`` and ``kv``, the gains of the
        position and velocity loops of the controller.  ``rate`` is 1000 Hz.

    Notes
    -----
    On the validation run the pulses are injected into the drive command, so ``vir``
    already contains them and ``F = gtau * vir`` is the whole force on the mass; adding
    ``pulses_N`` again would count them twice.  The record shows it: a least-squares fit
    of ``vir`` on ``qg - qm``, ``qm'`` and ``pulses_N`` gives 4.26e4 V/m, -267 V s/m
    (near ``kp * kv`` = 3.90e4 and ``-kv`` = -243) and 1.1 V per unit of ``pulses_N``
    (2 % relative residual); in the force balance with the
    published model, ``pulses_N`` gets a coefficient of -0.002 and the relative error
    of the published model's force is 4.8 % with ``F = gtau * vir`` against 8.0 % with
    ``gtau * vir + pulses_N`` (4.1 % on the estimation run; 20 Hz zero-phase low-pass,
    central differences).  Identified anew on the validation run with
    :data:`EMPS_EQUATION`, ``off`` comes out 2 % from the published value with
    ``F = gtau * vir``, and 78 % from it with ``pulses_N`` added (the pulses' mean).

    Raises
    ------
    InputDataError
        If ``run`` is not ``"estimation"`` or ``"validation"``.

    Examples
    --------
    >>> from algid.datasets import emps
    >>> rec = emps()
    >>> round(rec.gtau, 2), rec.F.shape
    (35.15, (24841,))
    """
    if run not in EMPS_FILES:
        raise InputDataError(f"unknown EMPS run {run!r}: use 'estimation' or 'validation'")
    variables = _emps_variables(EMPS_FILES[run])
    signals = {key: np.asarray(variables[key], dtype=np.float64).ravel().copy()
               for key in ("t", "qm", "vir", "qg")}
    constants = {key: float(np.asarray(variables[key]).item()) for key in ("gtau", "kp", "kv")}
    if "pulses_N" in variables:
        signals["pulses_N"] = np.asarray(variables["pulses_N"], dtype=np.float64).ravel()
    signals["F"] = constants["gtau"] * signals["vir"]
    return BenchmarkRecord(
        name=f"emps/{run}",
        signals=signals,
        rate=1000.0,
        constants=constants,
        description=("t: time [s]; qm: position [m]; vir: drive command [V]; "
                     "qg: reference position [m]; F: force on the mass [N]"
                     + ("; pulses_N: the pulses injected into the drive command"
                        if run == "validation" else "")),
        citation=EMPS_CITATION,
    )


#: The names :func:`export` knows, with what each writes.
EXPORTS = {
    "silverbox": ("silverbox.csv (t, V1, V2: 131072 samples at 610.35 Hz) and one file per "
                  "part: silverbox_arrow.csv, silverbox_estimation.csv, silverbox_test.csv"),
    "emps": ("emps_estimation.csv (t, qm, vir, qg, F: 24841 samples at 1 kHz) and "
             "emps_validation.csv (the same and pulses_N, already contained in vir and F)"),
}

#: The provenance note written beside the exported files (the records' README).
EXPORT_NOTE = "algid-datasets-README.md"


def _export_tables(name):
    """(file name, columns) of each CSV file :func:`export` writes for ``name``."""
    if name == "silverbox":
        record = silverbox()
        whole = {"t": np.arange(record.n_samples) / record.rate, **record.signals}
        tables = [("silverbox.csv", whole)]
        for part, (start, stop) in record.segments.items():
            tables.append((f"silverbox_{part}.csv",
                           {key: values[start:stop] for key, values in whole.items()}))
        return tables
    tables = []
    for run in EMPS_FILES:
        record = emps(run)
        names = ["t", "qm", "vir", "qg", "F"] + (["pulses_N"] if "pulses_N" in record else [])
        tables.append((f"emps_{run}.csv", {key: record[key] for key in names}))
    return tables


def _csv_text(columns):
    """CSV text: a header line, then one row per sample, each value as ``repr`` (the
    shortest text that reads back to the same float)."""
    rows = zip(*(np.asarray(values).tolist() for values in columns.values()))
    lines = [",".join(columns)]
    lines.extend(",".join(map(repr, row)) for row in rows)
    return "\n".join(lines) + "\n"


def _write_new(path, text, encoding, overwrite):
    """Write ``text`` to ``path`` without following a link there.

    Without ``overwrite``, ``path`` is created (``O_EXCL``: a file, a link or a dangling
    link already there is an error, never written through); with it, the text goes to a
    new file in the same folder that then replaces whatever ``path`` was (a link is
    replaced, not followed).
    """
    data = text.encode(encoding)
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) \
        | getattr(os, "O_BINARY", 0)
    target = path if not overwrite else path.with_name(f".{path.name}.{os.getpid()}.tmp")
    descriptor = os.open(target, flags, 0o666)
    try:
        with os.fdopen(descriptor, "wb") as handle:
            handle.write(data)
        if overwrite:
            os.replace(target, path)
    except BaseException:
        if overwrite:
            with contextlib.suppress(OSError):
                os.unlink(target)
        raise


def _holds(path, text):
    """Whether ``path`` is a regular file (not a link) that holds ``text``."""
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return False
        return path.read_bytes() == text.encode("utf-8")
    except OSError:
        return False


def export(name, folder, *, overwrite=False) -> list:
    """Write a shipped record as plain CSV files that ``algid identify`` reads directly.

    Every file has a header line and a time column ``t`` [s] (the Silverbox record,
    stored without one, gets ``t = row / 610.35``); the values are written exactly
    (each float as its shortest round-trip text).  The records' provenance note is
    written beside them as ``algid-datasets-README.md``.  A file of the same name is
    replaced only with ``overwrite=True``; a symbolic link there is never written
    through (with ``overwrite``, it is replaced by the file).

    Parameters
    ----------
    name : {"silverbox", "emps"}
        The record (see :data:`EXPORTS` for the files each writes).
    folder : str or os.PathLike
        Folder to write into; created if missing.
    overwrite : bool
        Replace files (or links) of the same names already in ``folder``; without it,
        nothing is written when one exists.

    Returns
    -------
    list of pathlib.Path
        The CSV files written.

    Raises
    ------
    InputDataError
        If ``name`` is not one of :data:`EXPORTS`.
    AlgidError
        If the folder or a file cannot be written, or a file of the same name exists
        (without ``overwrite``).

    Examples
    --------
    >>> import tempfile
    >>> from algid.datasets import export
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     print([path.name for path in export("emps", folder)])
    ['emps_estimation.csv', 'emps_validation.csv']

    Then, with the files written into a folder ``records``, on the command line::

        algid identify records/emps_estimation.csv --parameters "M Fv Fc off" \\
            --equation "M*qm'' + Fv*qm' + Fc*sign(qm') + off = F"
    """
    if name not in EXPORTS:
        raise InputDataError(f"unknown dataset {name!r} (known: {', '.join(EXPORTS)})")
    target = Path(folder)
    written = []
    tables = _export_tables(name)
    note = _data_file("README.md").read_text(encoding="utf-8")
    # the note of an export of the other record into the same folder stays as it is
    same_note = _holds(target / EXPORT_NOTE, note)
    names = [file_name for file_name, _ in tables] + ([] if same_note else [EXPORT_NOTE])
    if not overwrite:   # all checked first: nothing written when one would be replaced
        for file_name in names:
            if os.path.lexists(target / file_name):
                raise AlgidError(f"{target / file_name}: exists; not replaced without "
                                 f"overwrite=True (--force on the command line)")
    if os.path.lexists(target) and not target.is_dir():
        raise AlgidError(f"{target}: not a folder (a file of that name exists)")
    try:
        target.mkdir(parents=True, exist_ok=True)
        for file_name, columns in tables:
            path = target / file_name
            _write_new(path, _csv_text(columns), "ascii", overwrite)
            written.append(path)
        if not same_note:
            _write_new(target / EXPORT_NOTE, note, "utf-8", overwrite)
    except FileExistsError as exc:   # (created meanwhile, or a link: never followed)
        raise AlgidError(f"{exc.filename or target}: exists; not replaced without "
                         f"overwrite=True (--force on the command line)") from None
    except OSError as exc:
        raise AlgidError(f"{exc.filename or target}: cannot write "
                         f"({exc.strerror or exc})") from None
    return written

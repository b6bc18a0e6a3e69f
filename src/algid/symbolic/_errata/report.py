"""The errata report: the verdict on each printed equation, as text or JSON."""

from __future__ import annotations

import json
from dataclasses import dataclass

from algid.symbolic._errata import transcription
from algid.symbolic._errata.reference import reference_derivation
from algid.symbolic._errata.transcription import PrintedEquation
from algid.symbolic._printing import show

__all__ = ["EquationVerdict", "check_equation", "errata_report", "format_errata"]


@dataclass(frozen=True)
class EquationVerdict:
    """The computed verdict on one printed equation.

    Attributes
    ----------
    number : str
    printed : str
        The transcription, as text.
    correct : bool
    corrected : str or None
        The corrected form (``None`` when the printed one is right).
    explanation : str
        One line: what was compared, and where the printed form differs.
    reading : str
        How an ambiguous extraction was read.
    """

    number: str
    printed: str
    correct: bool
    corrected: str | None
    explanation: str
    reading: str = ""

    def as_dict(self) -> dict:
        """The verdict as a JSON-ready dictionary.

        Returns
        -------
        dict
            ``number``, ``correct``, ``printed``, ``corrected``, ``explanation`` and
            ``reading``.
        """
        return {"number": self.number, "correct": self.correct, "printed": self.printed,
                "corrected": self.corrected, "explanation": self.explanation,
                "reading": self.reading}


def check_equation(entry: PrintedEquation, table=None) -> EquationVerdict:
    """Run the check of one printed equation.

    Parameters
    ----------
    entry : PrintedEquation
    table : tuple of PrintedEquation, optional
        The whole transcription, for cross references (default :data:`PRINTED`).

    Returns
    -------
    EquationVerdict
    """
    correct, corrected, explanation = entry.evaluate(table)
    return EquationVerdict(number=entry.number, printed=show(entry.printed),
                           correct=bool(correct),
                           corrected=None if correct else (show(corrected) or None),
                           explanation=explanation, reading=entry.reading)


def errata_report(table=None) -> list:
    """Check every printed equation of Section 2 (and the footnote).

    Parameters
    ----------
    table : tuple of PrintedEquation, optional
        The transcription to check (default :data:`PRINTED`, read at call time).

    Returns
    -------
    list of EquationVerdict
        In the paper's order.
    """
    table = transcription.PRINTED if table is None else tuple(table)
    return [check_equation(entry, table) for entry in table]


def format_errata(verdicts, fmt: str = "text") -> str:
    """Render verdicts as text or JSON.

    Parameters
    ----------
    verdicts : list of EquationVerdict
    fmt : {"text", "json"}
        ``"text"``: one line per equation (``OK`` / ``WRONG`` and the explanation), then
        the corrected forms; ``"json"``: a list of objects with ``number``,
        ``correct``, ``printed``, ``corrected``, ``explanation`` (and ``reading``).

    Returns
    -------
    str
    """
    if fmt == "json":
        return json.dumps([v.as_dict() for v in verdicts], indent=2)
    if fmt != "text":
        raise ValueError(f"fmt must be 'text' or 'json', got {fmt!r}")
    wrong = [v for v in verdicts if not v.correct]
    model = reference_derivation().model
    lines = [f"Becedas et al. (2007), Section 2, checked against {model.equation_text()}: "
             f"{len(wrong)} of {len(verdicts)} printed equations are wrong", ""]
    width = max(len(v.number) for v in verdicts) + 2
    for v in verdicts:
        lines.append(f"{'(' + v.number + ')':<{width}} {'OK' if v.correct else 'WRONG':<5}  "
                     f"{v.explanation}")
    if wrong:
        lines += ["", "Corrected forms"]
        for v in wrong:
            if not v.corrected:
                continue
            body = v.corrected.split("\n")
            lines.append(f"({v.number}) {body[0]}")
            lines += [" " * (len(v.number) + 3) + b for b in body[1:]]
    return "\n".join(lines)

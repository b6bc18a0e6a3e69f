"""IdentificationResult.from_values: a parameter left out of the values is not a signal."""

import pytest

import algid
from algid import IdentificationResult


def test_a_parameter_without_a_value_is_refused_not_read_as_a_signal():
    """Its value left out, 'k' became a signal: the error came at simulate, as a column."""
    with pytest.raises(algid.InputDataError, match=r"^no value for 'k', which multiplies k\*y "
                                                   r"as a parameter would"):
        IdentificationResult.from_values("y'' + c*y' + k*y = u", {"c": 2.0})
    with pytest.raises(algid.InputDataError, match="no value for 'k'"):
        IdentificationResult.from_values("y'' + c*y' + k*y**3 = u", {"c": 2.0})


def test_a_signal_in_a_product_is_taken_when_the_parameters_are_stated():
    fit = IdentificationResult.from_values("y'' + c*y' + k*y = u", {"c": 2.0}, parameters="c")
    assert list(fit.values) == ["c"] and set(fit.model.signals) == {"y", "k", "u"}
    # a product of signals that appear nowhere else is not a forgotten parameter
    fit = IdentificationResult.from_values("y'' + c*y' = u*v", {"c": 2.0})
    assert set(fit.model.signals) == {"y", "u", "v"}
    full = IdentificationResult.from_values("y'' + c*y' + k*y = u", {"c": 2.0, "k": 3.0})
    assert full.values == {"c": 2.0, "k": 3.0}

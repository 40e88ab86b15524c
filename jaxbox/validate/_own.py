"""Whether an uncertainty or a validation given to a function is one of the fit it judges.

Apart from :mod:`jaxbox.validate._args` (a leaf) because it needs the classes of
:mod:`~jaxbox.validate._postsim` and :mod:`~jaxbox.validate._uncertainty`, which import
``_args`` themselves.
"""

from __future__ import annotations

from ._args import check_instance

__all__ = ["check_own"]


def check_own(result, uncertainty, validation):
    """``(uncertainty, validation)`` checked to be those of ``result`` (or None): a
    ``TypeError`` for another kind of object, a ``ValueError`` for those of another fit."""
    from ._postsim import Validation
    from ._uncertainty import Uncertainty

    check_instance(uncertainty, Uncertainty, "uncertainty", "jaxbox.validate.uncertainty")
    check_instance(validation, Validation, "validation", "jaxbox.validate.validate")
    problem = result.problem
    free = tuple(problem.free)
    if uncertainty is not None and tuple(uncertainty.free) != free:
        raise ValueError(
            f"uncertainty is of a fit with the free parameters {', '.join(uncertainty.free)}, "
            f"not of this one ({', '.join(free)}); pass uncertainty(result)"
        )
    if validation is not None and (
        validation.model != problem.model.name or len(validation.y_auto) != len(result.data)
    ):
        raise ValueError(
            f"validation is of another fit (model {validation.model}, {len(validation.y_auto)} "
            f"identification samples), not of this one (model {problem.model.name}, "
            f"{len(result.data)} samples); pass validate(result, valid)"
        )
    return uncertainty, validation

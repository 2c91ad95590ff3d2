"""A grey-box model of a machine, fitted to the library's own stored pairs.

The stored inputs of a machine's primitives say how the real machine differs from its
linear model: friction, a force ripple that depends on where the axis is, a constant
disturbance, a wrong mass or damping, an unmodelled lag. :func:`fit_greybox` fits those
terms (:data:`TERMS`) beside the linear model's inverse by least squares; the result,
:class:`GreyBox`, gives the input for any path (:meth:`GreyBox.inverse`), split into the
linear model's inverse, its linear correction and the nonlinear terms
(:meth:`GreyBox.terms`), which is what lets the warm start carry a stored signal over only
as far as a transform preserves it. :func:`refit_greybox` then refits, on a friction
machine, the linear model and the Coulomb levels on output error through the model run as a
machine (:func:`forward_model`), and :func:`polish` corrects the model-only input there.
"""

from primlib.greybox._features import LINEAR, NONLINEAR, POSITION, TERMS
from primlib.greybox._fit import fit_greybox
from primlib.greybox._model import GreyBox, Pair
from primlib.greybox._polish import forward_model, model_residual, polish
from primlib.greybox._refit import refit_greybox

__all__ = [
    "GreyBox",
    "LINEAR",
    "NONLINEAR",
    "POSITION",
    "Pair",
    "TERMS",
    "fit_greybox",
    "forward_model",
    "model_residual",
    "polish",
    "refit_greybox",
]

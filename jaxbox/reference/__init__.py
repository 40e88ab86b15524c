"""The reference route: Radau IIA direct collocation of the estimation problem.

The method of the reference study (De Coninck et al. 2016): states and parameters as decision
variables of one nonlinear program, the dynamics enforced at Radau collocation points, solved
simultaneously. jaxbox's default route is :func:`jaxbox.fit.fit_model` (single shooting with exact
simulation and Levenberg–Marquardt); this package cross-checks it and serves users who want the
collocation method itself.
"""

from ._collocation import OBJECTIVES as OBJECTIVES
from ._collocation import collocation_fit as collocation_fit
from ._collocation import collocation_simulate as collocation_simulate
from ._radau import MAX_POINTS as MAX_POINTS
from ._radau import RadauIIA as RadauIIA
from ._radau import radau_iia as radau_iia
from ._result import CollocationResult as CollocationResult

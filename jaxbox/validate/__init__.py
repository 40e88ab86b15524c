"""Validation: post-simulation, error metrics, uncertainty, residual analysis, verdicts, plots."""

from ._metrics import rmse as rmse
from ._metrics import simulation_error as simulation_error
from ._postsim import Validation as Validation
from ._postsim import ValidationError as ValidationError
from ._postsim import validate as validate
from ._residuals import CumulatedPeriodogram as CumulatedPeriodogram
from ._residuals import LjungBox as LjungBox
from ._residuals import OutputResiduals as OutputResiduals
from ._residuals import ResidualAnalysis as ResidualAnalysis
from ._residuals import analyse_residuals as analyse_residuals
from ._residuals import autocorrelation as autocorrelation
from ._residuals import cross_correlation as cross_correlation
from ._residuals import cumulated_periodogram as cumulated_periodogram
from ._residuals import ljung_box as ljung_box
from ._residuals import residual_stats as residual_stats
from ._uncertainty import Combination as Combination
from ._uncertainty import Uncertainty as Uncertainty
from ._uncertainty import sensitivities as sensitivities
from ._uncertainty import uncertainty as uncertainty

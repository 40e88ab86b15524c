"""Identification workflow: GreyBox and Case, initial guesses, forward selection, structure
search (and the heat-demand and steady-state forms of a held zone), persistence."""

from ._cases import Case as Case
from ._cases import run_cases as run_cases
from ._forms import FormChoice as FormChoice
from ._forward import Selection as Selection
from ._forward import candidate_models as candidate_models
from ._forward import forward_selection as forward_selection
from ._forward import forward_selection_many as forward_selection_many
from ._greybox import GreyBox as GreyBox
from ._greybox import load_greybox as load_greybox
from ._guess import Guess as Guess
from ._guess import lhs_starts as lhs_starts
from ._guess import manual_guess as manual_guess
from ._guess import naming_guess as naming_guess
from ._guess import parent_guess as parent_guess
from ._guess import state_guess as state_guess
from ._guess import state_ranges as state_ranges
from ._heat_demand import HeatDemandFit as HeatDemandFit
from ._heat_demand import heat_demand_fit as heat_demand_fit
from ._heat_demand import held_zone as held_zone
from ._persist import PersistError as PersistError
from ._persist import save_greybox as save_greybox
from ._search import CRITERIA as CRITERIA
from ._search import Search as Search
from ._search import SearchNode as SearchNode
from ._search import structure_search as structure_search
from ._steady import SteadyFit as SteadyFit
from ._steady import steady_fit as steady_fit

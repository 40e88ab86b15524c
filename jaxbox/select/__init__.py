"""Identification workflow: GreyBox and Case, initial guesses, forward selection, structure
search, persistence."""

from ._cases import Case as Case
from ._cases import run_cases as run_cases
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
from ._persist import PersistError as PersistError
from ._persist import save_greybox as save_greybox
from ._search import CRITERIA as CRITERIA
from ._search import Search as Search
from ._search import SearchNode as SearchNode
from ._search import structure_search as structure_search

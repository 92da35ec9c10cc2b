"""beamid: large static and dynamic deformation of flexible beam chains, and
the inverse problem (after McVay 1996).

The numerical work is done in Fortran; this package wraps it.

>>> import beamid
>>> r = beamid.solve_static(beamid.pace(), beamid.TipForce(fy=8.0), wrt=("EI1",))
>>> round(r.tip_y, 6)
0.628434
"""
from .errors import BeamidError, ConvergenceError, InputError, OutputError
from .model import Model, cantilever, pace
from .loads import Modal, RadialWire, Release, TipForce, TipLoad, TipMoment
from .static import Shape, StaticResult, solve_static
from .fe import axial_modes_linear, buckling_load, fe_path, fe_static, modes
from .decks import Deck, read_deck, run, write_deck
from .tables import reproduce
from .measurements import Measurements, read_measurements
from .channels import Sensor, read_channels
from . import observations
from .estimation import identify, Identification, FitResult, fit, simulate_measurements
from .dynamics import Run, simulate
from .load_histories import Chirp, HalfSine, SpinUp, Step, Table
from .dynamics import FrictionEvent
from .dynamics import SENSITIVITY_QUANTITIES
# the dynamics name also under an explicit alias
simulate_dynamics = simulate
from .diagnosis import (Comparison, Diagnosis, Effect, Ladder, add_effect, compare, diagnose,
                        improve, register_effect)
from . import dyn_diagnosis as _dyn_diagnosis  # registers the dynamic candidates
from .dyn_diagnosis import DYNAMIC_CANDIDATES, TimeComparison
from .consistency import Consistency, consistency
from . import robust as _robust  # fills in fit's checks of its own end (issue 30)
from .design import Advice, design
from .modal import ModalResult, ModePairing, mac, modal_analysis, pair_modes, plot_mac
from .modal_data import UFFModal, modal_rows, read_uff

__all__ = [
    "BeamidError", "ConvergenceError", "InputError", "OutputError",
    "Model", "pace", "cantilever",
    "TipForce", "TipMoment", "TipLoad", "RadialWire", "Release", "Modal",
    "solve_static", "StaticResult", "Shape",
    "Deck", "read_deck", "write_deck", "run", "reproduce",
    "Measurements", "read_measurements", "fit", "FitResult", "simulate_measurements",
    "Sensor", "read_channels", "observations",
    "identify", "Identification",
    "simulate", "simulate_dynamics", "Run", "FrictionEvent", "SENSITIVITY_QUANTITIES",
    "HalfSine", "Step", "Chirp", "Table", "SpinUp",
    "fe_static", "fe_path", "buckling_load", "modes", "axial_modes_linear",
    "compare", "diagnose", "add_effect", "improve", "register_effect", "Effect",
    "Comparison", "Diagnosis", "Ladder",
    "consistency", "Consistency", "design", "Advice",
    "DYNAMIC_CANDIDATES", "TimeComparison",
    "modal_analysis", "ModalResult", "mac", "pair_modes", "ModePairing", "plot_mac",
    "modal_rows", "read_uff", "UFFModal",
]
__version__ = "0.1.0"

"""The old import path of the problem: kept until recorder.py moves to problem.py."""
from .model import ModelOptions  # noqa: F401
from .problem import FingertipProblem  # noqa: F401
from .tissues import WU2004

Tissues = lambda: WU2004  # temporary: recorder.py calls Tissues() for the paper's set

"""sim4endor: reinforcement-learning guidewire navigation in 3D vessels on MuJoCo."""

from sim4endor import _gl
from sim4endor.envs.gym import register_all as _register_gym_ids

__version__ = "0.1.0"

# Before MuJoCo or dm_control is imported: without a display, a backend that is installed
# instead of GLFW's warning (see sim4endor._gl).
_gl.choose_headless_backend()
# gymnasium >= 1.0 does not discover third-party ids: register ours (cheap, no MuJoCo import).
_register_gym_ids()

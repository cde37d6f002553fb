"""sim4endor: reinforcement-learning guidewire navigation in 3D vessels on MuJoCo."""

from sim4endor.envs.gym import register_all as _register_gym_ids

__version__ = "0.1.0"

# gymnasium >= 1.0 does not discover third-party ids: register ours (cheap, no MuJoCo import).
_register_gym_ids()

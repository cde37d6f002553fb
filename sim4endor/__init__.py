"""sim4endor: reinforcement-learning guidewire navigation in 3D vessels on MuJoCo."""

__version__ = "0.1.0"

"""Bench tests of the wire model, as a laboratory tests a guidewire: static beams and the
scripted steering of :mod:`.validation`, the S-tube roll of :mod:`.torque`, the dead-end push
of :mod:`.push`.

They drive :class:`sim4endor.physics.GuidewirePhysics`, so they sit above it rather than in
:mod:`sim4endor.models`, which the physics builds on. The tests and
``experiments/benchmarks/guidewire_validation.py`` use them. The tip-load test stays in
:mod:`sim4endor.models.tip_load`: the wire catalogue derives its core profiles from it.
"""

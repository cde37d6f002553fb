"""The wire catalogue: named 0.014" guidewire presets and the cardiologist's tip shaping.

The presets are data (``wires.toml`` beside this module, read on first use, never at
import); this module turns them into :class:`~sim4endor.models.guidewire.GuidewireConfig`.

Example:
    >>> import math
    >>> from sim4endor.models import wires
    >>> wires.names()
    ('paper', 'workhorse', 'intermediate', 'stiff')
    >>> wire = wires.preset("workhorse", tip=wires.TipShape(0.0015, math.radians(60)))
    ... # doctest: +SKIP

``paper`` is the paper's wire (``GuidewireConfig()``'s physics), the phantoms' default; at
fidelity ``"fast"`` it is ``GuidewireConfig()`` unchanged, the published model of Table I.
Every preset comes at a fidelity (:mod:`sim4endor.models.fidelity`): ``"converged"`` by
default, ``"fast"`` for exploring. The others model real wire classes (workhorse ≈ 1 gf,
intermediate 3 gf, stiff CTO 12.4 gf tip load) with a tapered core whose distal diameter is
derived from the rated tip load, and a coat whose friction is data too (``[coatings]``:
the workhorse is hydrophilic, 0.03; the others hydrophobic, 0.1); see ``wires.toml`` and
docs/guidewire.md.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from typing import Any, TypeVar

from sim4endor.errors import Sim4EndoRError
from sim4endor.models import fidelity as fidelities
from sim4endor.models.guidewire import INCH, SECONDARY_CURVE_LENGTH, GuidewireConfig

#: The preset that reproduces the paper (``GuidewireConfig()``).
PAPER = "paper"
#: Shape lengths a cardiologist bends into a coronary tip (m): "a curve at the tip of the
#: guidewire which is roughly the length of the diameter of the vessel proximal to the lesion"
#: (C. M. Gibson, "Guidewire general techniques", Wikidoc), so up to about 5 mm for side branches
#: of a 3.5-4.5 mm proximal RCA, LAD or left main; 1-2 mm for narrow distal vessels and CTOs.
SHAPE_LENGTH_RANGE = (0.001, 0.005)
#: Shape angles of an angled tip (rad).
SHAPE_ANGLE_RANGE = (math.radians(30.0), math.radians(90.0))
#: Where a secondary curve may lie (m from the distal end to its middle) and how far it
#: bends (rad). "The primary curve should match the greatest angle to be negotiated, whereas
#: the secondary curve is chosen to match the size of the vessel" (*Interventional Cardiology*,
#: Wiley, an edited textbook, ch. 5 on coronary hardware, beside its Fig. 5.9; Mishra & Bahl,
#: Indian Heart J 2009;61:275-280: a 2 mm primary curve at 45-60°, "sometimes even a proximal
#: secondary curve"): a few millimetres behind the tip, about a proximal coronary's diameter.
SECONDARY_DISTANCE_RANGE = (0.004, 0.010)
SECONDARY_ANGLE_RANGE = (math.radians(15.0), math.radians(60.0))
#: The "J": a 3 mm arc curled through 150°, the tip pointing back at the shaft's side.
J_LENGTH = 0.003
J_ANGLE = math.radians(150.0)
_MM = 1e-3
_Value = TypeVar("_Value")


class WireCatalogueError(Sim4EndoRError, ValueError):
    """An unknown preset or a bad tip shape; the message names it and the valid choices."""


@dataclass(frozen=True)
class TipShape:
    """The shape a cardiologist bends into the wire's tip: a circular arc (the primary curve),
    optionally with a secondary curve behind it, in the same plane and to the same side.

    Attributes:
        length: Shaped length of the tip (m), 1–5 mm.
        angle: Total bend over that length (rad), 30–90°.
        secondary_distance: Distance from the distal end to the middle of the secondary
            curve (m), 4–10 mm and behind the tip; ignored without ``secondary_angle``.
        secondary_angle: Bend of the secondary curve (rad), 15–60°; 0 (default): none.
    """

    length: float
    angle: float
    secondary_distance: float = 0.0
    secondary_angle: float = 0.0

    def __post_init__(self) -> None:
        self._check("length", self.length, SHAPE_LENGTH_RANGE, "")
        self._check("angle", self.angle, SHAPE_ANGLE_RANGE, "; for a J use tip='J'")
        if self.secondary_angle:
            self._check("secondary_angle", self.secondary_angle, SECONDARY_ANGLE_RANGE,
                        "; 0 for none")
            nearest, farthest = SECONDARY_DISTANCE_RANGE
            self._check("secondary_distance", self.secondary_distance,
                        (max(nearest, self.length + SECONDARY_CURVE_LENGTH / 2), farthest),
                        f"; it lies behind the {self.length * 1e3:g} mm tip")

    @staticmethod
    def _check(field: str, value: float, bounds: tuple[float, float], hint: str) -> None:
        """Raises :class:`WireCatalogueError` naming ``field`` unless ``value`` is in
        ``bounds`` (angles in rad, lengths in m; the message gives degrees or mm too)."""
        low, high = bounds
        if math.isfinite(value) and low - 1e-12 <= value <= high + 1e-12:
            return
        if field.endswith("angle"):
            rule = (f"{math.degrees(low):g}–{math.degrees(high):g}° (in rad: {low:.4f}–"
                    f"{high:.4f})")
            unit = "rad"
        else:
            rule, unit = f"{low * 1e3:g}–{high * 1e3:g} mm (in m: {low}–{high})", "m"
        raise WireCatalogueError(f"TipShape.{field} must be {rule}, got {value!r} {unit}{hint}.")

    def as_mapping(self) -> dict[str, float]:
        """Plain data, as :func:`resolve` takes it back (and a run's exported policy.json
        records it): ``length`` and ``angle``, and the secondary curve's fields if it has one."""
        fields = dataclasses.asdict(self)
        if not self.secondary_angle:
            del fields["secondary_distance"], fields["secondary_angle"]
        return fields

    @classmethod
    def degrees(cls, length_mm: float, angle_deg: float, secondary_distance_mm: float = 0.0,
                secondary_angle_deg: float = 0.0) -> TipShape:
        """The shape from the units a cardiologist uses (mm and degrees)."""
        return cls(length_mm * _MM, math.radians(angle_deg), secondary_distance_mm * _MM,
                   math.radians(secondary_angle_deg))


@dataclass(frozen=True)
class WireEntry:
    """One catalogue entry: what the preset models, its rating and where that comes from.

    Attributes:
        name: Preset name.
        description: One line.
        config: The wire with the preset's own tip shape.
        rated_tip_load_gf: Published tip load (gf); ``None`` for ``paper``.
        rating_source: Where the rating comes from (URLs).
        modelled_on: The real wire or class the preset stands for.
        core_material: ``"nitinol"`` or ``"stainless_steel"``.
        coating: The jacket's coat, a name of :func:`coatings` (its friction is the
            config's); ``""`` for ``paper``.
    """

    name: str
    description: str
    config: GuidewireConfig
    rated_tip_load_gf: float | None = None
    rating_source: str = ""
    modelled_on: str = ""
    core_material: str = "nitinol"
    coating: str = ""


@functools.cache
def _data() -> dict[str, Any]:
    text = resources.files("sim4endor.models").joinpath("wires.toml").read_text("utf-8")
    return tomllib.loads(text)


@functools.cache
def _catalogue() -> dict[str, WireEntry]:
    materials = _data()["materials"]
    return {name: _entry(name, raw, materials) for name, raw in _data()["presets"].items()}


def coatings() -> dict[str, float]:
    """Returns the catalogue's coats and their sliding friction coefficients (``wires.toml``)."""
    return {name: float(raw["friction"]) for name, raw in _data()["coatings"].items()}


def coating_friction(name: str) -> float:
    """Returns the sliding friction coefficient of coat ``name``.

    Raises:
        WireCatalogueError: For an unknown coat; the message lists the valid ones.
    """
    return _named(coatings(), name, "coating")


def _named(table: Mapping[str, _Value], name: str, what: str) -> _Value:
    """``table[name]``, or an error that names ``name`` and lists the valid names."""
    try:
        return table[name]
    except (KeyError, TypeError):
        raise WireCatalogueError(
            f"Unknown wire {what} {name!r}; valid: {list(table)}."
        ) from None


def _entry(name: str, raw: Mapping[str, Any], materials: Mapping[str, Any]) -> WireEntry:
    if name == PAPER:
        numerics = fidelities.numerics(fidelities.DEFAULT, name)
        return WireEntry(name, raw["description"], numerics.apply(GuidewireConfig()))
    material = materials[raw["core_material"]]
    profile = tuple((s * _MM, d * _MM) for s, d in raw["core_profile_mm"])
    shape = TipShape.degrees(**raw["tip_shape"])
    config = GuidewireConfig(
        outer_diameter=0.014 * INCH,
        core_diameter=profile[-1][1],  # the shaft core: the reference of every joint factor
        core_profile=profile,
        youngs_modulus=material["youngs_modulus_gpa"] * 1e9,
        shear_modulus=material["shear_modulus_gpa"] * 1e9,
        density=material["density_kg_m3"],
        tip_stiffness_factor=1.0,  # the taper makes the tip soft
        friction=coating_friction(raw["coating"]),
    )
    return WireEntry(
        name=name, description=raw["description"],
        config=fidelities.numerics(fidelities.DEFAULT, name).apply(shaped(config, shape)),
        rated_tip_load_gf=float(raw["rated_tip_load_gf"]), rating_source=raw["rating_source"],
        modelled_on=raw["modelled_on"], core_material=raw["core_material"],
        coating=raw["coating"],
    )


@dataclass(frozen=True)
class WireVariation:
    """How one unit of a preset differs from the next (``wires.toml``'s ``[variation]``,
    with the sources of its ranges): a draw scales the wire's moduli (its tip load) and
    friction, and moves its tip shape, each seed giving one unit.

    Attributes:
        stiffness_scale: Range of the factor on the Young's and shear moduli (log-uniform).
        friction_scale: Range of the factor on the friction coefficient (log-uniform).
        tip_length: Largest change of the shaped tip's length (m, uniform ±).
        tip_angle: Largest change of its bend (rad, uniform ±).
        secondary_angle: Largest change of a secondary curve's bend (rad, uniform ±).
    """

    stiffness_scale: tuple[float, float]
    friction_scale: tuple[float, float]
    tip_length: float
    tip_angle: float
    secondary_angle: float

    @classmethod
    def catalogue(cls) -> WireVariation:
        """The catalogue's ranges."""
        raw = _data()["variation"]
        return cls(tuple(raw["stiffness_scale"]), tuple(raw["friction_scale"]),
                   raw["tip_length_mm"] * _MM, math.radians(raw["tip_angle_deg"]),
                   math.radians(raw["secondary_angle_deg"]))

    def draw(self, wire: GuidewireConfig, seed: int) -> GuidewireConfig:
        """The unit of ``wire`` that ``seed`` draws (the same seed, the same unit), its tip
        kept within :class:`TipShape`'s ranges; a tip outside them (a J) keeps its shape."""
        import numpy as np

        rng = np.random.default_rng([seed, _VARIATION_STREAM])
        stiffness, friction = (math.exp(rng.uniform(math.log(low), math.log(high)))
                               for low, high in (self.stiffness_scale, self.friction_scale))
        scaled = dataclasses.replace(
            wire, youngs_modulus=wire.youngs_modulus * stiffness,
            shear_modulus=wire.shear_modulus * stiffness, friction=wire.friction * friction)
        low, high = SHAPE_ANGLE_RANGE
        if not low <= wire.tip_angle <= high:
            return scaled
        length = _clipped(wire.tip_length + rng.uniform(-1, 1) * self.tip_length,
                          SHAPE_LENGTH_RANGE)
        angle = _clipped(wire.tip_angle + rng.uniform(-1, 1) * self.tip_angle,
                         SHAPE_ANGLE_RANGE)
        secondary = rng.uniform(-1, 1) * self.secondary_angle
        secondary_distance = wire.secondary_distance
        if wire.secondary_angle:
            secondary = _clipped(wire.secondary_angle + secondary, SECONDARY_ANGLE_RANGE)
            # The secondary curve stays behind the tip, however long the tip is drawn.
            secondary_distance = max(secondary_distance, length + SECONDARY_CURVE_LENGTH / 2)
        return dataclasses.replace(
            scaled, tip_length=length, tip_angle=angle,
            secondary_angle=secondary if wire.secondary_angle else 0.0,
            secondary_distance=secondary_distance)


#: The seed stream of :meth:`WireVariation.draw`, apart from the tree's own draws.
_VARIATION_STREAM = 83


def _clipped(value: float, bounds: tuple[float, float]) -> float:
    return min(max(value, bounds[0]), bounds[1])


def names() -> tuple[str, ...]:
    """Returns the preset names, ``paper`` first."""
    return tuple(_catalogue())


def entry(name: str) -> WireEntry:
    """Returns the catalogue entry of preset ``name``.

    Raises:
        WireCatalogueError: For an unknown name; the message lists the valid ones.
    """
    return _named(_catalogue(), name, "preset")


def shaped(wire: GuidewireConfig, tip: TipShape | str) -> GuidewireConfig:
    """Returns ``wire`` with its tip shaped: a :class:`TipShape`, ``"J"``, or the command
    line's text ``"LENGTH_MM,ANGLE_DEG"`` (:func:`parse_tip`).

    Raises:
        WireCatalogueError: For text :func:`parse_tip` rejects, or anything else.
    """
    if isinstance(tip, str):
        tip = parse_tip(tip)
    if tip == "J":
        return dataclasses.replace(wire, tip_length=J_LENGTH, tip_angle=J_ANGLE,
                                   secondary_distance=0.0, secondary_angle=0.0)
    if not isinstance(tip, TipShape):
        raise WireCatalogueError(
            f"tip must be a TipShape(length m, angle rad), 'J' or 'LENGTH_MM,ANGLE_DEG', "
            f"got {tip!r}."
        )
    return dataclasses.replace(wire, tip_length=tip.length, tip_angle=tip.angle,
                               secondary_distance=tip.secondary_distance,
                               secondary_angle=tip.secondary_angle)


def parse_tip(text: str) -> TipShape | str:
    """A tip shape as written on a command line or in a run's config: ``LENGTH_MM,ANGLE_DEG``
    (``"3,75"``: the distal 3 mm bent through 75°), the same followed by a secondary curve's
    ``,DISTANCE_MM,ANGLE_DEG`` (``"2,60,7,40"``: and 40° centred 7 mm from the end), or
    ``"J"``.

    Raises:
        WireCatalogueError: For any other text, or a shape outside :class:`TipShape`'s ranges.
    """
    if text.strip().upper() == "J":
        return "J"
    try:
        numbers = [float(part) for part in text.split(",")]
    except ValueError:
        numbers = []
    if len(numbers) not in (2, 4):
        raise WireCatalogueError(
            f"A tip shape is LENGTH_MM,ANGLE_DEG (e.g. 3,75), optionally followed by a "
            f"secondary curve's DISTANCE_MM,ANGLE_DEG (e.g. 2,60,7,40), or J; got {text!r}."
        )
    try:
        return TipShape.degrees(*numbers)
    except WireCatalogueError:  # its message is in SI units; say it in the ones written
        (short, long), (low, high) = SHAPE_LENGTH_RANGE, SHAPE_ANGLE_RANGE
        (near, far), (least, most) = SECONDARY_DISTANCE_RANGE, SECONDARY_ANGLE_RANGE
        raise WireCatalogueError(
            f"Tip shape {text!r}: the shaped length must be {short / _MM:g}-{long / _MM:g} mm "
            f"and the angle {math.degrees(low):g}-{math.degrees(high):g} deg (or J); a "
            f"secondary curve {near / _MM:g}-{far / _MM:g} mm from the end, behind the tip, "
            f"and {math.degrees(least):g}-{math.degrees(most):g} deg."
        ) from None


def preset(name: str, tip: TipShape | str | None = None,
           fidelity: str = fidelities.DEFAULT) -> GuidewireConfig:
    """Returns the wire of preset ``name``, its tip shaped by ``tip`` if given, with the
    numerical settings of ``fidelity`` (:mod:`sim4endor.models.fidelity`).

    Args:
        name: One of :func:`names`.
        tip: ``None`` keeps the preset's shape; a :class:`TipShape` or ``"J"`` reshapes it.
        fidelity: ``"converged"`` (default) or ``"fast"``.

    Raises:
        WireCatalogueError: For an unknown name or a bad tip.
        sim4endor.models.fidelity.FidelityError: For an unknown fidelity.
    """
    wire = fidelities.numerics(fidelity, name).apply(entry(name).config)
    return wire if tip is None else shaped(wire, tip)


def resolve(wire: str | GuidewireConfig | Mapping[str, Any] | None,
            fidelity: str | None = None) -> GuidewireConfig:
    """A user's wire setting as a config: a preset name, a config, or a mapping.

    A mapping holds :class:`GuidewireConfig` fields, optionally with ``"preset"`` (the base,
    default ``paper``), ``"coating"`` (a name of :func:`coatings`: sets ``friction``, so
    not both) and ``"tip"`` (a :class:`TipShape`, ``"J"``, the command line's ``"5,60"``
    in mm and degrees, or ``{"length":, "angle":}`` in m and rad). ``None`` gives ``paper``.
    A preset, named or as a mapping's base, takes the numerical settings of ``fidelity``
    (:mod:`sim4endor.models.fidelity`; ``None``: the default, ``"converged"``); a
    mapping's own fields override them. A config is returned as it is: it carries its own.

    Raises:
        WireCatalogueError: For an unknown preset, field, coating or tip, a coating and a
            friction both given, or a fidelity given with a config.
        sim4endor.models.fidelity.FidelityError: For an unknown fidelity.
    """
    if isinstance(wire, GuidewireConfig):
        if fidelity is not None:
            raise WireCatalogueError(
                f"A GuidewireConfig carries its own numerical settings, so fidelity "
                f"{fidelity!r} cannot apply to it; name a preset (or a mapping with 'preset') "
                "instead, or set the config's fields."
            )
        return wire
    fidelity = fidelity or fidelities.DEFAULT
    if wire is None:
        return preset(PAPER, fidelity=fidelity)
    if isinstance(wire, str):
        return preset(wire, fidelity=fidelity)
    if isinstance(wire, Mapping):
        fields = dict(wire)
        base = preset(fields.pop("preset", PAPER), fidelity=fidelity)
        tip = fields.pop("tip", None)
        coating = fields.pop("coating", None)
        valid = {f.name for f in dataclasses.fields(GuidewireConfig)}
        unknown = sorted(set(fields) - valid)
        if unknown:
            raise WireCatalogueError(
                f"Unknown wire fields {unknown}; valid: 'preset', 'coating', 'tip' and "
                f"{sorted(valid)}."
            )
        if coating is not None:
            if "friction" in fields:
                raise WireCatalogueError(
                    "A wire mapping sets its friction by 'coating' or by 'friction', not both; "
                    f"got coating={coating!r} and friction={fields['friction']!r}."
                )
            fields["friction"] = coating_friction(coating)
        if isinstance(tip, Mapping):
            shape_fields = {f.name for f in dataclasses.fields(TipShape)}
            if not {"length", "angle"} <= set(tip) <= shape_fields:
                raise WireCatalogueError(
                    f"A wire's tip mapping needs 'length' (m) and 'angle' (rad), and takes a "
                    f"secondary curve's 'secondary_distance' (m) and 'secondary_angle' (rad); "
                    f"got {sorted(tip)}."
                )
            tip = TipShape(**{key: float(value) for key, value in tip.items()})
        wire_config = dataclasses.replace(base, **fields)
        return wire_config if tip is None else shaped(wire_config, tip)
    raise WireCatalogueError(
        f"A wire must be a preset name ({list(names())}), a GuidewireConfig or a mapping of "
        f"its fields, got {wire!r}."
    )

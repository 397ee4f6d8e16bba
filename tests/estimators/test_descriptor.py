"""A descriptor refuses what it cannot mean (a quantity or a plot of no output), and builds only once the
registry has attached its factory."""

from __future__ import annotations

import pytest

from gaitscope.estimators.descriptor import Descriptor, PlotHint, Tunable, out
from gaitscope.estimators.tbe import DESCRIPTOR as TBE
from gaitscope.estimators.tbe import TimingBasedEstimator


def _toy(**kw: object) -> Descriptor:
    args: dict[str, object] = {"name": "toy", "label": "Toy", "inputs": ("heel_strike",)}
    args["outputs"] = (out("y", "1", "a number"),)
    return Descriptor(**(args | kw))  # type: ignore[arg-type]


def test_an_output_that_is_a_channel_takes_its_meaning_from_the_channel_table() -> None:
    assert out("heel_strike", "bool").meaning == "an ipsilateral heel strike at this sample"
    with pytest.raises(ValueError, match="say what it means"):
        out("y", "1")


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"quantities": {"z": "phase"}}, "quantity of z, which is not an output"),
        ({"quantities": {"y": "cadence"}}, "unknown quantity 'cadence'"),
        ({"plots": (PlotHint("p", "P", "1", ("z",)),)}, r"plot p draws \['z'\]"),
        ({"plots": (PlotHint("p", "P", "1", ()),)}, r"plot p draws \[\]"),
        ({"outputs": (out("y", "1", "a"), out("y", "1", "b"))}, "an output is named twice"),
        ({"tunables": (Tunable("k", 2.0, 1.0),)}, "tunable k has min 2.0 > max 1.0"),
    ],
)
def test_a_descriptor_refuses_what_it_cannot_mean(kw: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        _toy(**kw)


def test_it_builds_with_the_factory_the_registry_attaches() -> None:
    with pytest.raises(TypeError, match="tbe has no factory"):
        TBE.build(None)
    est = TBE.built_by(lambda c: TimingBasedEstimator()).build(None)
    assert (est.name, est.outputs, est.tunables) == ("tbe", TBE.declared_outputs, TBE.tunable_names)
    assert TBE.built_by(lambda c: TimingBasedEstimator()) == TBE  # the factory is not part of what it is

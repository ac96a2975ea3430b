"""Every field of every typed config declares what it accepts (imm_model/typed_config.py), and each is fed values it
must refuse, built directly and read from JSON: one line naming the field, every time."""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

import pytest

from imm_model.families.diffusion.recipes import DiffusionTrainConfig
from imm_model.families.diffusion.sampler import DiffusionConfig, Guidance
from imm_model.families.gan.config import ModelConfig
from imm_model.families.gan.recipes import NAMED, TrainConfig
from imm_model.model.classifier_config import ClassifierConfig
from imm_model.typed_config import FieldsOf, Flag, Interval, ListOf, Name, OneOf, PathText, constraint_of

CONFIGS = (TrainConfig, ModelConfig, ClassifierConfig, DiffusionTrainConfig, DiffusionConfig, Guidance)


def invalid_values(check: Any) -> list[Any]:
    """Values `check` must refuse: of the wrong type, and of the right type just outside what it accepts."""
    if isinstance(check, Interval):
        values: list[Any] = ["1", None, True]
        step = 1 if check.kind is int else 1e-3
        if check.low is not None:
            values.append(check.low - step if check.closed in ("both", "left") else check.low)
        if check.high is not None:
            values.append(check.high + step if check.closed in ("both", "right") else check.high)
        if check.kind is int:
            values.append(float(check.low if check.low is not None else 0) + 0.5)
        else:
            values += [float("nan"), float("inf")]
        return values
    if isinstance(check, OneOf):
        return ["no-such-option", 1, None]
    if isinstance(check, Flag):
        return ["yes", 1, None]
    if isinstance(check, Name):
        return ["", "a/b", "two\nlines", "x" * (check.max_length + 1), 3]
    if isinstance(check, PathText):
        return ["two\nlines", "x" * (check.max_length + 1), 3, None]
    if isinstance(check, ListOf):
        values = ["not a list", 5, [invalid_values(check.item)[0]]]
        return values + ([[]] if check.min_length else [])
    if isinstance(check, FieldsOf):
        return [5, "x", {"no_such_field": 1}]
    raise AssertionError(f"no invalid values known for {check!r}")


def probes() -> list[tuple[type, str, Any]]:
    return [(cls, f.name, bad) for cls in CONFIGS for f in fields(cls) for bad in invalid_values(constraint_of(f))]


@pytest.mark.parametrize("cls", CONFIGS, ids=lambda c: c.__name__)
def test_every_field_declares_a_constraint_that_its_default_meets(cls):
    for f in fields(cls):
        check = constraint_of(f)
        assert check is not None, f"{cls.__name__}.{f.name} declares no constraint"
        assert check.accepts(getattr(cls(), f.name)), f"{cls.__name__}.{f.name}: its default is refused"


@pytest.mark.parametrize("cls, name, bad", probes(), ids=lambda x: x.__name__ if isinstance(x, type) else repr(x)[:30])
def test_an_invalid_value_is_refused_in_one_line_naming_the_field(cls, name, bad):
    with pytest.raises(ValueError) as built:
        replace(cls(), **{name: bad})
    with pytest.raises(ValueError) as read:
        cls.from_dict(cls().to_dict() | {name: bad})
    for err in (built.value, read.value):
        message = str(err)
        assert f"{name} must be" in message or f"{name}: " in message, message
        assert "\n" not in message and len(message) <= 300, message


def test_the_fields_that_had_no_range_check_are_checked():
    for name, bad in (("adv_warmup_epochs", -1), ("adv_ramp_epochs", -1), ("rotate_deg", -5.0), ("rotate_deg", 400.0),
                      ("min_epochs", -1), ("select_from_epoch", -2), ("seed", -1), ("seed", 2**40)):
        with pytest.raises(ValueError, match=f"training config: {name} must be"):
            replace(TrainConfig(), **{name: bad})


def test_rules_across_fields_and_the_named_recipes():
    with pytest.raises(ValueError, match="model config: body_parts must be joint indices below num_joints"):
        ModelConfig(num_joints=3, body_parts=((0, 1), (2, 3)))
    with pytest.raises(ValueError, match="classifier config: start_centred must be false for interaction inputs"):
        ClassifierConfig(inputs="interaction", start_centred=True)
    with pytest.raises(ValueError, match="training config: model: model config: dropout must be"):
        TrainConfig(model={"dropout": 1.0})
    for cfg in NAMED.values():  # every shipped recipe meets its constraints, also read back from JSON
        assert TrainConfig.from_dict(cfg.to_dict()) == cfg

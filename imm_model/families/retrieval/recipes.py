"""The retrieval family's one recipe: nothing to set, since it learns nothing (`imm train --config retrieval` writes a
checkpoint that names the fold's training data)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from imm_model.typed_config import Name, checked_kwargs, param, validate


@dataclass(frozen=True)
class RetrievalConfig:
    # the recipe's name (run folders and reports carry it); a config built without one is no named recipe
    name: str = param("custom", Name())

    def __post_init__(self) -> None:
        validate(self, "retrieval config")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> RetrievalConfig:
        return cls(**checked_kwargs(cls, d, "retrieval config"))


NAMED: dict[str, RetrievalConfig] = {"retrieval": RetrievalConfig(name="retrieval")}

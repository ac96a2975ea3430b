"""The checks every registered model family passes (as scikit-learn's common estimator checks do): load through the
registry, synthesize in the world and the canonical frame, seeds, labels and leaders refused in one line, a save/load
round trip, the numpy runtime against torch, the latent embedding. A new family is checked by adding its folder and
registry line; its bundled (or smallest) checkpoint goes in CHECKPOINTS."""

from __future__ import annotations

import numpy as np
import pytest

from imm_model.data.dataset import InteractionDataset
from imm_model.errors import DataFormatError, IMMError, LabelError
from imm_model.families import FAMILIES, load_model, load_recipe, recipe_names
from imm_model.families.base import ReactionModel
from imm_model.paths import SAMPLE_DATA, SAMPLE_MODELS

# one checkpoint per registered family: the bundled ones
CHECKPOINTS = {"gan": SAMPLE_MODELS["gan"], "diffusion": SAMPLE_MODELS["diffusion"], "retrieval": SAMPLE_MODELS["retrieval"]}


def test_every_registered_family_has_a_checkpoint_here():
    assert set(CHECKPOINTS) == set(FAMILIES)


@pytest.fixture(scope="module")
def data():
    return InteractionDataset.load(SAMPLE_DATA)


@pytest.fixture(scope="module", params=sorted(FAMILIES))
def model(request) -> ReactionModel:
    return load_model(CHECKPOINTS[request.param])


def leader_of(data, i: int = 5) -> np.ndarray:
    return data.world(i)[0]


def test_the_registry_loads_the_checkpoints_family(model):
    family = FAMILIES[model.family]
    assert isinstance(model, family.model_class()) and model.title == family.title
    assert type(ReactionModel.load(model.path)) is type(model)  # the public entry point, through the registry


def test_synthesize_in_the_leaders_world_frame(model, data):
    leader = leader_of(data)
    follower = model.synthesize(leader, {"hugging": 1.0})
    assert follower.shape == leader.shape and follower.dtype == np.float32 and np.isfinite(follower).all()
    # the world path is the canonical path mapped back: the same reaction, in the leader's frame
    prepared = model.prepare_leader(leader)
    canonical = model.synthesize_canonical(prepared.canonical, model.label_vector({"hugging": 1.0}))
    np.testing.assert_allclose(follower, prepared.to_world(canonical, model.skeleton), atol=1e-5)
    # a partner within arm's reach of the leader, not metres away
    assert np.linalg.norm(follower[:, 2] - leader[:, 2], axis=-1).mean() < 3.0


def test_one_batch_gives_what_one_leader_at_a_time_gives(model, data):
    leaders = [leader_of(data, i) for i in (1, 7, 40)]
    vec = model.label_vector({"pushing": 1.0, "kicking": -0.5})
    batch = model.synthesize_leaders(leaders, vec, [3, 3, 3])
    for leader, follower in zip(leaders, batch, strict=True):
        np.testing.assert_allclose(follower, model.synthesize(leader, {"pushing": 1.0, "kicking": -0.5}, seed=3), atol=1e-4)


def test_seeds_pick_reactions_only_for_a_seeded_model(model, data):
    leader = leader_of(data)
    drawn = model.synthesize(leader, {"kicking": 1.0}, seed=4, samples=3)
    assert drawn.shape == (3, *leader.shape)
    # a seed is repeatable (drawn alone or in a batch of three: the same reaction, to float precision)
    np.testing.assert_allclose(drawn[0], model.synthesize(leader, {"kicking": 1.0}, seed=4), atol=1e-5)
    if model.settings.seed:
        assert not np.allclose(drawn[0], drawn[1])
    else:
        np.testing.assert_array_equal(drawn[0], drawn[1])


@pytest.mark.parametrize("label, words", [({"dancing": 1.0}, "unknown class 'dancing'"), ({"kicking": float("nan")}, "finite"),
                                          ([1.0, 0.0], "expected 6 values"), ("kicking", "not a string"),
                                          ({"kicking": 11.0}, "outside the range")])
def test_a_bad_label_is_refused_in_one_line(model, data, label, words):
    with pytest.raises(LabelError) as err:
        model.synthesize(leader_of(data), label)
    assert words in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("seed, samples", [(-1, None), (1.5, None), (True, None), (0, 0), (0, 65)])
def test_a_bad_seed_or_sample_count_is_refused_in_one_line(model, data, seed, samples):
    with pytest.raises(LabelError) as err:
        model.synthesize(leader_of(data), {"kicking": 1.0}, seed=seed, samples=samples)
    assert "\n" not in str(err.value)


def test_a_bad_leader_is_refused_in_one_line(model, data):
    leader = leader_of(data).copy()
    leader[3, 2, 1] = np.nan
    for bad, words in ((leader, "NaN"), (leader[:1], "1 frame"), (leader[:, :10], "10 joints")):
        with pytest.raises(DataFormatError) as err:
            model.synthesize(bad, {"kicking": 1.0})
        assert words in str(err.value) and "\n" not in str(err.value)


def test_a_saved_model_loads_as_itself(model, data, tmp_path):
    model.save(tmp_path / "again.safetensors")
    again = load_model(tmp_path / "again.safetensors")
    assert type(again) is type(model) and again.class_names == model.class_names
    leader = leader_of(data)
    np.testing.assert_array_equal(again.synthesize(leader, {"hugging": 0.5}, seed=2), model.synthesize(leader, {"hugging": 0.5}, seed=2))


def test_the_numpy_runtime_gives_what_torch_gives(model, data):
    twin = model.on_torch()
    if twin is None:
        pytest.skip(f"{model.title} has no numpy runtime beside torch")
    leader = leader_of(data)
    np.testing.assert_allclose(twin.synthesize(leader, {"shaking_hands": 1.0}, seed=1),
                               model.synthesize(leader, {"shaking_hands": 1.0}, seed=1), atol=1e-4)
    np.testing.assert_allclose(twin.latent(leader, {"shaking_hands": 1.0}), model.latent(leader, {"shaking_hands": 1.0}),
                               atol=1e-4, rtol=1e-4)


def test_the_latent_embedding_is_one_finite_vector_per_leader_and_label(model, data):
    leader = leader_of(data)
    z = model.latent(leader, {"hugging": 1.0})
    assert z.ndim == 1 and np.isfinite(z).all()
    np.testing.assert_array_equal(z, model.latent(leader, {"hugging": 1.0}))
    assert model.latent_canonical_batch([data.canonical(i)[0] for i in range(3)], np.eye(6, dtype=np.float32)[:3]).shape == (3, len(z))


def test_a_family_refuses_the_settings_it_does_not_take(model, data):
    if not model.settings.spread:
        with pytest.raises(LabelError, match="no spread setting"):
            model.spread = 0.5
    if not model.settings.memory:
        with pytest.raises(LabelError, match="no sampler"):
            model.use_memory(0.5, data)


def test_every_named_recipe_belongs_to_one_family_and_builds_as_named():
    names = recipe_names()
    assert len(names) == len(set(names))
    for name in names:
        family, config = load_recipe(name)
        assert config.name == name and family.recipes()[name] == config


def test_a_config_built_without_arguments_is_no_named_recipe():
    for family in FAMILIES.values():
        config_class = type(next(iter(family.recipes().values())))
        assert config_class().name not in recipe_names()


def test_a_recipe_override_the_family_lacks_is_one_line():
    with pytest.raises(ValueError, match="steps does not apply"):
        load_recipe("imm-steer", steps=10)
    with pytest.raises(ValueError, match="seed does not apply"):
        load_recipe("retrieval", seed=1)


def test_a_checkpoint_of_an_unknown_family_is_refused_in_one_line(tmp_path):
    import json
    import shutil

    shutil.copy(CHECKPOINTS["retrieval"], tmp_path / "x.safetensors")
    meta = json.loads(CHECKPOINTS["retrieval"].with_suffix(".json").read_text())
    (tmp_path / "x.json").write_text(json.dumps(meta | {"family": "mystery"}))
    with pytest.raises(IMMError, match="family 'mystery' is none of gan, diffusion, retrieval"):
        load_model(tmp_path / "x.safetensors")

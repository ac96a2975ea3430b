"""Nothing the user has is lost: every output is planned before anything is written (existing files need --force,
inputs are never replaced, two outputs never share a name) and written atomically; a checkpoint's weights and
sidecar are checked against each other; --overwrite exports the new model; `imm reproduce` locks its folders and
its workers end with it; the studio's export copies never overwrite each other."""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from imm_model.checkpoint import DIGEST, final_checkpoint, load_checkpoint, save_checkpoint
from imm_model.cli import main
from imm_model.errors import CheckpointError, IMMError
from imm_model.outputs import Output, plan_outputs, write_atomic, write_files
from imm_model.paths import SAMPLE_GAN

SEQUENCE = "s01s02/03/001"


def _refused(capsys, *needles: str) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _generate(*args: str) -> int:
    return main(["generate", "--label", "kicking=1", *args])


@pytest.fixture(scope="module")
def leaders(tmp_path_factory, sample_data):
    """A 15-joint BVH leader (as `imm generate` writes them) and two .npz leaders."""
    d = tmp_path_factory.mktemp("leaders")
    assert _generate("--sequence", SEQUENCE, "--out", str(d / "made.bvh")) == 0
    shutil.copy(d / "made.leader.bvh", d / "t.leader.bvh")
    for name, i in (("a.npz", 0), ("b.npz", 1)):
        np.savez(d / name, leader=sample_data.world(i)[0])
    return d


# ---- imm generate ----------------------------------------------------------------------------------------------
def test_generate_never_replaces_its_bvh_leader_input(leaders, tmp_path, capsys):
    src = tmp_path / "t.leader.bvh"
    shutil.copy(leaders / "t.leader.bvh", src)
    before = _files(tmp_path)
    assert _generate("--leader", str(src), "--out", str(tmp_path / "t.bvh"), "--force") == 2
    _refused(capsys, "an input of this command", "t.leader.bvh")
    assert _files(tmp_path) == before  # not even t.bvh


def test_generate_refuses_an_existing_leader_copy_and_replaces_it_atomically_with_force(tmp_path, capsys):
    (tmp_path / "r.leader.bvh").write_text("mine")
    assert _generate("--sequence", SEQUENCE, "--out", str(tmp_path / "r.bvh")) == 2
    _refused(capsys, "r.leader.bvh", "pass --force")
    assert _files(tmp_path) == {"r.leader.bvh": b"mine"}
    inode = (tmp_path / "r.leader.bvh").stat().st_ino
    assert _generate("--sequence", SEQUENCE, "--out", str(tmp_path / "r.bvh"), "--force") == 0
    assert (tmp_path / "r.leader.bvh").read_text().startswith("HIERARCHY")
    assert (tmp_path / "r.leader.bvh").stat().st_ino != inode  # a new file renamed over the old, not rewritten
    assert sorted(_files(tmp_path)) == ["r.bvh", "r.leader.bvh"]  # no temporary file left


def test_generate_batch_refuses_an_existing_item_leader_copy(leaders, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "a_kicking+1.leader.bvh").write_text("mine")
    assert _generate("--leader", str(leaders / "a.npz"), str(leaders / "b.npz"), "--format", "bvh", "--out", str(out)) == 2
    _refused(capsys, "a_kicking+1.leader.bvh", "pass --force")
    assert _files(out) == {"a_kicking+1.leader.bvh": b"mine"}


def test_generate_batch_items_with_one_name_are_refused_not_lost(leaders, tmp_path, capsys):
    for folder in ("A", "B"):
        (tmp_path / folder).mkdir()
        shutil.copy(leaders / "a.npz", tmp_path / folder / "walk.npz")
    out = tmp_path / "out"
    assert _generate("--leader", str(tmp_path / "A" / "walk.npz"), str(tmp_path / "B" / "walk.npz"), "--out", str(out)) == 2
    _refused(capsys, "written twice", "A/walk.npz", "B/walk.npz")
    shutil.copy(leaders / "t.leader.bvh", tmp_path / "A" / "walk.bvh")  # walk.bvh and walk.npz in one folder
    assert _generate("--leader", str(tmp_path / "A"), "--out", str(out)) == 2
    _refused(capsys, "written twice", "walk.bvh", "walk.npz")
    assert not out.exists()


def test_generate_batch_counts_the_files_it_writes(leaders, tmp_path, capsys):
    out = tmp_path / "out"
    assert _generate("--leader", str(leaders / "a.npz"), str(leaders / "b.npz"), "--format", "bvh", "--out", str(out)) == 0
    assert len(_files(out)) == 4 and "wrote 4 files (2 leaders x 1 labels, each with its leader copy)" in capsys.readouterr().out


def test_generate_never_writes_over_a_checkpoint_sidecar(tmp_path, capsys):
    for suffix in (".safetensors", ".json"):
        shutil.copy(SAMPLE_GAN.with_suffix(suffix), tmp_path / f"ck{suffix}")
    before = _files(tmp_path)
    assert _generate("--sequence", SEQUENCE, "--checkpoint", str(tmp_path / "ck.safetensors"), "--out",
                     str(tmp_path / "ck.json"), "--force") == 2
    _refused(capsys, "ck.json", "an input of this command")
    assert _files(tmp_path) == before


def test_a_full_disk_is_one_line_and_leaves_the_old_output(tmp_path, capsys, monkeypatch):
    import imm_model.data.bvh as bvh

    out = tmp_path / "x.bvh"
    assert _generate("--sequence", SEQUENCE, "--out", str(out)) == 0
    before = _files(tmp_path)
    capsys.readouterr()

    def full(path, *args, **kwargs):
        Path(path).write_text("partial")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(bvh, "write_bvh", full)
    assert _generate("--sequence", SEQUENCE, "--out", str(out), "--force") == 2
    _refused(capsys, "x.bvh", "No space left on device")
    assert _files(tmp_path) == before  # both files as they were, no temporary file left


# ---- imm evaluate: refused before evaluating ----------------------------------------------------------------------
def test_evaluate_reports_never_replace_the_checkpoint_sidecar_or_each_other(tmp_path, capsys):
    for suffix in (".safetensors", ".json"):
        shutil.copy(SAMPLE_GAN.with_suffix(suffix), tmp_path / f"X{suffix}")
    before = _files(tmp_path)
    assert main(["evaluate", "--checkpoint", str(tmp_path / "X.safetensors"), "--json", str(tmp_path / "X.json"),
                 "--force", "--quiet"]) == 2
    _refused(capsys, "X.json", "an input of this command")
    assert main(["evaluate", "--json", str(tmp_path / "r.out"), "--markdown", str(tmp_path / "r.out"), "--quiet"]) == 2
    _refused(capsys, "--json and --markdown are the same file")
    assert main(["evaluate", "--figures", str(tmp_path / "X.json"), "--quiet"]) == 2
    _refused(capsys, "X.json is a file, not a folder")
    assert _files(tmp_path) == before


# ---- the planner and the writers ----------------------------------------------------------------------------------
def test_plan_outputs_sees_through_links_and_refuses_as_a_whole(tmp_path):
    data = tmp_path / "data.npz"
    data.write_bytes(b"x")
    os.link(data, tmp_path / "hard.npz")
    (tmp_path / "soft.npz").symlink_to(data)
    for alias in ("hard.npz", "soft.npz"):
        with pytest.raises(IMMError, match="an input of this command"):
            plan_outputs([Output(tmp_path / alias)], [data], force=True)
    with pytest.raises(IMMError, match="is a file, not a folder"):
        plan_outputs([Output(data / "x.npz")])
    with pytest.raises(IMMError, match="is a folder"):
        plan_outputs([Output(tmp_path)])
    plan_outputs([Output(tmp_path / "new" / "deep" / "x.npz"), Output(tmp_path / "y.npz", "--json")], [data])


def test_write_files_renames_all_or_nothing(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    write_files([(a, "1"), (b, b"2")])

    def fail(path):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))

    with pytest.raises(IMMError, match="b.txt: could not write it .Permission denied.") as err:
        write_files([(a, "new"), (b, fail)])
    assert "\n" not in str(err.value)
    assert _files(tmp_path) == {"a.txt": b"1", "b.txt": b"2"}  # a was not replaced either, no temporary file
    write_atomic(a, "3")
    assert _files(tmp_path) == {"a.txt": b"3", "b.txt": b"2"}


# ---- checkpoints ---------------------------------------------------------------------------------------------------
def _pair(tmp_path: Path, name: str, epoch: int, shift: float) -> Path:
    tensors, meta = load_checkpoint(SAMPLE_GAN)
    tensors = {k: v + shift if v.is_floating_point() else v for k, v in tensors.items()}
    path = tmp_path / f"{name}.safetensors"
    save_checkpoint(path, tensors, meta | {"training": meta["training"] | {"epoch": epoch}})
    return path


def test_a_mismatched_checkpoint_pair_is_refused(tmp_path):
    from imm_model.inference import ReactionModel

    path = _pair(tmp_path, "ck", 10, 0.0)
    old_sidecar = path.with_suffix(".json").read_text()
    _pair(tmp_path, "ck", 15, 1e-3)  # as if killed between the two renames: weights of epoch 15, sidecar of 10
    assert ReactionModel.load(path).info["training"]["epoch"] == 15
    path.with_suffix(".json").write_text(old_sidecar)
    for framework in ("pt", "np"):
        with pytest.raises(CheckpointError, match="come from different saves") as err:
            load_checkpoint(path, framework)
        assert "\n" not in str(err.value) and "delete ck.json" in str(err.value)
    path.with_suffix(".json").unlink()  # the advice: the weights carry their own metadata
    assert load_checkpoint(path)[1]["training"]["epoch"] == 15
    # a sidecar without a digest beside weights with one was not saved with them
    meta = json.loads(old_sidecar)
    del meta[DIGEST]
    path.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(CheckpointError, match="not saved with these weights"):
        load_checkpoint(path)


def test_checkpoints_saved_before_digests_load_and_are_still_matched(tmp_path):
    from safetensors.torch import save_file

    tensors, meta = load_checkpoint(SAMPLE_GAN)
    assert DIGEST not in meta and DIGEST not in json.loads(SAMPLE_GAN.with_suffix(".json").read_text())
    old = tmp_path / "old.safetensors"  # written as the code before digests wrote them
    save_file(tensors, str(old), metadata={"imm": json.dumps(meta, sort_keys=True)})
    old.with_suffix(".json").write_text(json.dumps(meta))
    assert load_checkpoint(old, "np")[1]["training"] == meta["training"]
    old.with_suffix(".json").write_text(json.dumps(meta | {"training": meta["training"] | {"epoch": 3}}))
    with pytest.raises(CheckpointError, match="training records differ"):
        load_checkpoint(old)


def test_an_edited_sidecar_of_the_same_weights_still_loads(tmp_path):
    path = _pair(tmp_path, "ck", 10, 0.0)
    side = json.loads(path.with_suffix(".json").read_text()) | {"note": "edited by hand"}
    path.with_suffix(".json").write_text(json.dumps(side))
    assert load_checkpoint(path)[1]["note"] == "edited by hand"


def test_a_full_disk_while_saving_keeps_the_old_pair(tmp_path, monkeypatch):
    path = _pair(tmp_path, "ck", 10, 0.0)
    before = _files(tmp_path)
    real = Path.write_bytes

    def full(self, data):
        if self.name.startswith(".ck.json"):
            real(self, data[:10])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", full)
    with pytest.raises(CheckpointError, match="ck.json: could not write it .No space left on device.") as err:
        _pair(tmp_path, "ck", 15, 1e-3)
    assert "\n" not in str(err.value)
    monkeypatch.undo()
    assert _files(tmp_path) == before and load_checkpoint(path)[1]["training"]["epoch"] == 10


# ---- imm train --overwrite --export, --resume ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def overwritten_run(tmp_path_factory):
    """A run directory holding a previous run's refit final.safetensors, trained again (tiny, 1 epoch, no refit) with
    --overwrite --export."""
    from imm_model.families.gan.recipes import IMM

    d = tmp_path_factory.mktemp("train")
    tiny = replace(IMM, model=IMM.model | dict(stream_embed=16, encoder_hidden=8, decoder_hidden=16, attention_dim=8,
                                               disc_hidden=8), epochs=1, checkpoint_every=1, refit=False)
    (d / "tiny.json").write_text(json.dumps(tiny.to_dict()))
    fold = d / "ov" / "fold-s04"
    fold.mkdir(parents=True)
    for suffix in (".safetensors", ".json"):  # the previous run's shipped model
        shutil.copy(SAMPLE_GAN.with_suffix(suffix), fold / f"final{suffix}")
    (fold / "notes.txt").write_text("not the run's")
    base = ["train", "--config", str(d / "tiny.json"), "--fold", "s04", "--out", str(d / "ov"), "--quiet", "--threads", "1"]
    assert main([*base, "--overwrite", "--export", str(d / "e.safetensors")]) == 0
    return d, fold, base


def test_overwrite_then_export_ships_the_new_model(overwritten_run):
    d, fold, _ = overwritten_run
    assert not (fold / "final.safetensors").exists() and not (fold / "final.json").exists()
    assert (fold / "notes.txt").read_text() == "not the run's"  # only the run's own files are cleared
    assert final_checkpoint(fold) == fold / "best.safetensors"  # what `imm evaluate --run` reads
    exported, best = load_checkpoint(d / "e.safetensors")[0], load_checkpoint(fold / "best.safetensors")[0]
    assert exported.keys() == {k for k in best if k.startswith("generator.")}
    assert all(torch.equal(exported[k], best[k]) for k in exported)


def test_export_never_replaces_the_runs_own_checkpoints(overwritten_run, capsys):
    d, fold, base = overwritten_run
    before = _files(fold)
    assert main([*base, "--overwrite", "--export", str(fold / "best.safetensors")]) == 2
    _refused(capsys, "an input of this command")
    assert _files(fold) == before


def test_resume_refuses_a_mismatched_pair(overwritten_run, capsys):
    d, fold, base = overwritten_run
    tensors, meta = load_checkpoint(fold / "last.safetensors")
    save_checkpoint(d / "other.safetensors", {k: v + 1 if v.is_floating_point() else v for k, v in tensors.items()}, meta)
    shutil.copy(d / "other.json", fold / "last.json")  # the sidecar of another save
    before, config = _files(fold), (fold.parent / "config.json").stat()
    assert main([*base, "--resume", "--epochs", "2"]) == 2
    _refused(capsys, "last.safetensors", "come from different saves")
    assert _files(fold) == before
    after = (fold.parent / "config.json").stat()  # the run's config not rewritten for a resume that was refused
    assert (after.st_ino, after.st_mtime_ns) == (config.st_ino, config.st_mtime_ns)


def test_train_refuses_a_fold_another_trainer_is_working_in(overwritten_run, capsys):
    from imm_model.outputs import FolderLock

    d, fold, base = overwritten_run
    before, config = _files(fold), (fold.parent / "config.json").stat()
    with FolderLock(fold, "run"):  # as `imm reproduce` holds a run it trains
        assert main([*base, "--overwrite"]) == 2
        _refused(capsys, "fold-s04: in use by another `imm reproduce`", f"pid {os.getpid()}")
    with FolderLock(fold, "--out", "imm train"):
        assert main([*base, "--overwrite", "--epochs", "2"]) == 2
        _refused(capsys, "in use by another `imm train`")
    after = (fold.parent / "config.json").stat()
    assert _files(fold) == before and (after.st_ino, after.st_mtime_ns) == (config.st_ino, config.st_mtime_ns)


def test_resume_refuses_a_checkpoint_of_another_recipe_before_writing(overwritten_run, capsys):
    d, fold, base = overwritten_run
    tensors, meta = load_checkpoint(fold / "best.safetensors")
    save_checkpoint(fold / "last.safetensors", tensors, meta | {"train_config": meta["train_config"] | {"lr_g": 0.5}})
    before, config = _files(fold), (fold.parent / "config.json").stat()
    assert main([*base, "--resume", "--epochs", "2"]) == 2
    _refused(capsys, "last.safetensors: saved with a different training config")
    after = (fold.parent / "config.json").stat()
    assert _files(fold) == before and (after.st_ino, after.st_mtime_ns) == (config.st_ino, config.st_mtime_ns)


# ---- imm reproduce -------------------------------------------------------------------------------------------------
def test_reproduce_refuses_a_folder_another_reproduce_holds(tmp_path, capsys):
    from imm_model.outputs import LOCK_NAME, FolderLock

    args = ["reproduce", "--folds", "s04", "--epochs", "1", "--tables", "afd", "--backend", "local"]
    with FolderLock(tmp_path / "rep", "--out"):
        assert main([*args, "--out", str(tmp_path / "rep")]) == 2
        _refused(capsys, "in use by another `imm reproduce`", f"pid {os.getpid()}")
    with FolderLock(tmp_path / "shared-runs", "--runs"):
        assert main([*args, "--out", str(tmp_path / "other"), "--runs", str(tmp_path / "shared-runs")]) == 2
        _refused(capsys, "--runs", "in use")
    assert [p.name for p in (tmp_path / "rep").iterdir()] == [LOCK_NAME]  # nothing written
    assert [p.name for p in (tmp_path / "shared-runs").iterdir()] == [LOCK_NAME]


def _children(pid: int) -> set[int]:
    kids = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        kids |= {int(k) for k in (task / "children").read_text().split()}
    return kids


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_killing_the_runner_ends_its_workers(tmp_path, sig):
    """A worker busy with a long job (a trainer) ends when the runner is killed, even with -9."""
    started = tmp_path / "started"  # the job writes its worker's pid here, then runs long
    (tmp_path / "long_job.py").write_text("import os, time\n\ndef run(started):\n    with open(started + '.tmp', 'w') as f:\n"
                                          "        f.write(str(os.getpid()))\n    os.replace(started + '.tmp', started)\n"
                                          "    time.sleep(120)\n")
    script = (f"import sys\nsys.path.insert(0, {str(tmp_path)!r})\nimport long_job\nfrom imm_model.reproduce.runner import Runner, Task\n"
              f"with Runner(backend='local') as r:\n    r.run([Task('long', long_job.run, ({str(started)!r},))], 'jobs')\n")
    driver = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline, workers = time.monotonic() + 60, set()
        while time.monotonic() < deadline and (len(workers) < (os.cpu_count() or 1) or not started.exists()):
            workers |= {p for p in _children(driver.pid) if "spawn_main" in Path(f"/proc/{p}/cmdline").read_text()}
            time.sleep(0.2)  # the pool (a worker per core) up and the job running in one of them
        assert started.exists() and int(started.read_text()) in workers, (started.exists(), workers)
        driver.send_signal(sig)
        driver.wait(30)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and any(_alive(p) for p in workers):
            time.sleep(0.2)
        assert not any(_alive(p) for p in workers)
    finally:
        driver.kill()
        driver.wait()


# ---- the studio's export copies ------------------------------------------------------------------------------------
def test_studio_export_copies_never_overwrite_and_use_safe_names(tmp_path):
    from explorer.ui.exports import Exports

    upload = SimpleNamespace(name="take.bvh")
    session = SimpleNamespace(files=SimpleNamespace(name=lambda ext: f"{Path(upload.name).stem}_neutral.{ext}",
                                                    bvh=lambda character: f"BVH of {upload.name}".encode()))
    page = SimpleNamespace(session=session, state=SimpleNamespace(notice=""), guarded=lambda fn: fn,
                           trigger=lambda name: (lambda fn: fn))
    exports = Exports(page, None, tmp_path / "exports", attach=bytes)
    assert exports.export_bvh("follower") == b"BVH of take.bvh"
    upload.name = "elsewhere/take.bvh"  # another take of the same name
    exports.export_bvh("follower")
    assert _files(tmp_path / "exports") == {"take_neutral.follower.bvh": b"BVH of take.bvh",
                                            "take_neutral.follower-2.bvh": b"BVH of elsewhere/take.bvh"}
    assert "take_neutral.follower-2.bvh" in page.state.notice
    for bad in ("../../x", "follower/../../x"):
        with pytest.raises(ValueError, match="unknown character"):
            exports.export_bvh(bad)
    with pytest.raises(ValueError, match="unknown video format"):
        exports.export_video("../gif")
    upload.name = "../..\n.hidden take.bvh"
    exports.export_bvh("leader")
    names = sorted(_files(tmp_path / "exports"))
    assert len(names) == 3 and all(re.fullmatch(r"[A-Za-z0-9_+-][A-Za-z0-9._+-]*", n) for n in names), names
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exports"]

"""Hostile command lines: nothing the user has is replaced without --force (nor ever an input of the same run, nor by
a second writer at the same moment), no path the user names can hang a reader or fill memory, a checkpoint whose
weights are absurd is refused at load, and each refusal is one line, rc 2, naming the file or field."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from imm_model.cli import main
from imm_model.errors import CheckpointError, DataFormatError
from imm_model.paths import SAMPLE_DATA, SAMPLE_DIFFUSION

FIXTURES = Path(__file__).parent / "fixtures"
BVH = FIXTURES / "bvh/cmu_01_01.bvh"
SBU_RAW = FIXTURES / "sbu"
ENV = os.environ | {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def one_line_error(capsys, *expected: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("imm "), err
    for text in expected:
        assert text in err, err
    return err


# ---- nothing replaced without --force ---------------------------------------------------------------------------------
def test_generate_with_memory_never_replaces_the_data_it_reads(tmp_path, capsys):
    data = tmp_path / "mydata.npz"
    shutil.copy(SAMPLE_DATA, data)
    before = data.read_bytes()
    rc = main(["generate", "--leader", str(BVH), "--checkpoint", str(SAMPLE_DIFFUSION), "--memory", "0.5", "--data", str(data),
               "--label", "kicking=1", "--out", str(data), "--force"])
    assert rc == 2
    one_line_error(capsys, "that is an input of this command", "mydata.npz")
    assert data.read_bytes() == before


def test_build_sample_replaces_nothing_without_force_and_never_touches_a_user_tmp_file(tmp_path, capsys):
    out, user_tmp = tmp_path / "mine.npz", tmp_path / "mine.npz.tmp"
    out.write_bytes(b"mine")
    user_tmp.write_bytes(b"also mine")
    assert main(["data", "build-sample", "--raw", str(SBU_RAW), "--out", str(out)]) == 2
    one_line_error(capsys, "mine.npz: the file exists; pass --force")
    assert out.read_bytes() == b"mine"
    assert main(["data", "build-sample", "--raw", str(SBU_RAW), "--out", str(out), "--force"]) == 0
    assert out.read_bytes()[:2] == b"PK" and user_tmp.read_bytes() == b"also mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.npz", "mine.npz.tmp"]  # no temporary file left


@pytest.mark.parametrize("existing", ["mine.safetensors", "mine.json"])
def test_build_judge_replaces_no_part_of_the_pair_without_force(tmp_path, capsys, existing):
    (tmp_path / existing).write_text("mine")
    assert main(["data", "build-judge", "--out", str(tmp_path / "mine.safetensors")]) == 2  # refused before training
    one_line_error(capsys, f"{existing}: the file exists; pass --force")
    assert [p.name for p in tmp_path.iterdir()] == [existing] and (tmp_path / existing).read_text() == "mine"


def test_an_atomic_write_without_replace_refuses_a_file_created_after_the_plan(tmp_path):
    from imm_model.errors import IMMError
    from imm_model.outputs import write_files

    first, second = tmp_path / "a.safetensors", tmp_path / "a.json"
    second.write_text("another writer's")  # created between the plan and the write
    with pytest.raises(IMMError, match="a.json: the file exists"):
        write_files([(first, b"weights"), (second, "sidecar")], replace=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json"] and second.read_text() == "another writer's"


AT_THE_LINE = r"""
import sys, time
from pathlib import Path

def at_the_line(sync: Path, name: str, trial: int) -> None:  # until both racers have reached trial `trial`
    (sync / f"{name}-{trial}").touch()
    deadline = time.monotonic() + 120
    while len(list(sync.glob(f"*-{trial}"))) < 2:
        if time.monotonic() > deadline:
            sys.exit("the other racer never came")
        time.sleep(0.001)
"""
WRITER = AT_THE_LINE + r"""
import json
from imm_model.errors import IMMError
from imm_model.outputs import Output, plan_outputs, write_files
sync, name, targets = Path(sys.argv[1]), sys.argv[2], json.loads(sys.argv[3])
results = []
for i, target in enumerate(targets):
    at_the_line(sync, name, i)
    try:  # as a command writes: its plan, then its files (a checkpoint and its sidecar)
        files = [(Path(target), name.encode()), (Path(target).with_suffix(".json"), name)]
        plan_outputs([Output(path) for path, _ in files])
        write_files(files, replace=False)
        results.append("wrote")
    except IMMError as err:
        results.append(str(err))
print(json.dumps(results))
"""
RACER = AT_THE_LINE + r"""
import contextlib, io, json
from imm_model.cli import main
sync, name, warm, trials = Path(sys.argv[1]), sys.argv[2], json.loads(sys.argv[3]), json.loads(sys.argv[4])
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
    # imports and the first model load out of the way, so that the trials start together
    assert main([*warm, "--out", str(sync / f"warm-{name}.npz")]) == 0
results = []
for i, argv in enumerate(trials):
    at_the_line(sync, name, i)
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = main(argv)
    results.append({"rc": rc, "err": err.getvalue()})
print(json.dumps(results))
"""


def race(tmp_path: Path, script: str, *args: str) -> list[list]:
    """Two processes run `script` (sync folder, racer name, args), meeting at the line before each trial."""
    sync = tmp_path / "sync"
    sync.mkdir()
    racers = [subprocess.Popen([sys.executable, "-c", script, str(sync), name, *args], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=ENV) for name in ("a", "b")]
    outcomes = []
    for racer in racers:
        out, err = racer.communicate(timeout=240)
        assert racer.returncode == 0, err[-2000:]
        outcomes.append(json.loads(out))
    return outcomes


def test_two_processes_writing_one_pair_never_both_succeed(tmp_path):
    """Ten times, two processes plan and write the same checkpoint pair at the same moment, without --force: one
    writes both files, the other is refused, and no file holds a mix of the two."""
    targets = [str(tmp_path / f"trial{i}.safetensors") for i in range(10)]
    a, b = race(tmp_path, WRITER, json.dumps(targets))
    for i, target in enumerate(targets):
        assert sorted([a[i], b[i]]).count("wrote") == 1, (i, a[i], b[i])
        winner, refused = ("a", b[i]) if a[i] == "wrote" else ("b", a[i])
        assert "the file exists" in refused and "--force" in refused, (i, a[i], b[i])
        assert Path(target).read_text() == winner and Path(target).with_suffix(".json").read_text() == winner
    assert not list(tmp_path.rglob(".*.tmp"))


@pytest.mark.slow
def test_two_generate_runs_at_one_out_never_both_succeed(tmp_path, sample_data):
    """Two processes start the same `imm generate` (no --force) at the same moment, ten times: one file, then one
    folder of a batch, in turn. Each time one writes and the other is refused in one line, having written nothing."""
    common = ["generate", "--sequence", sample_data.sequence_ids[0], "--label", "kicking=1"]
    outs = [tmp_path / (f"trial{i}.npz" if i % 2 == 0 else f"batch{i}") for i in range(10)]
    trials = [[*common, "--out", str(out)] if i % 2 == 0 else [*common, "--label", "hugging=1", "--out", str(out)]
              for i, out in enumerate(outs)]  # a batch of two labels
    outcomes = race(tmp_path, RACER, json.dumps(common), json.dumps(trials))
    for i, (a, b) in enumerate(zip(*outcomes, strict=True)):
        winner, loser = (a, b) if a["rc"] == 0 else (b, a)
        assert (winner["rc"], loser["rc"]) == (0, 2), (i, a, b)
        lines = loser["err"].strip().splitlines()
        assert "the file exists" in lines[-1] and "--force" in lines[-1], (i, loser)
        files = [outs[i]] if i % 2 == 0 else sorted(outs[i].iterdir())
        assert len(files) == (1 if i % 2 == 0 else 2), (i, files)
    assert not [p for p in tmp_path.rglob(".*.tmp")]


# ---- no path hangs a reader or fills memory ---------------------------------------------------------------------------
CLI_CHILD = r"""
import contextlib, io, json, resource, signal, sys, time
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))  # a reader of /dev/zero fails here instead of filling memory
from imm_model.cli import main

class Overrun(Exception):
    pass

def alarm(signum, frame):
    raise Overrun()

signal.signal(signal.SIGALRM, alarm)
results = []
for argv in json.loads(sys.argv[1]):
    err, start = io.StringIO(), time.perf_counter()
    signal.alarm(int(sys.argv[2]))
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = main(argv)
    except Overrun:
        rc = "overrun"
    except BaseException as e:
        rc = f"crashed: {type(e).__name__}"
    signal.alarm(0)
    results.append({"rc": rc, "err": err.getvalue(), "seconds": time.perf_counter() - start})
print(json.dumps(results))
"""


def run_cli_cases(argvs: list[list[str]], seconds: int = 20) -> list[dict]:
    """Each command line in one child process, each under its own alarm: a hang is reported, not waited for."""
    run = subprocess.run([sys.executable, "-c", CLI_CHILD, json.dumps(argvs), str(seconds)], capture_output=True, text=True,
                         timeout=60 + seconds * len(argvs), env=ENV)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout)


@pytest.mark.slow
def test_no_named_path_hangs_or_fills_memory(tmp_path):
    fifo, zero = tmp_path / "pipe.npz", tmp_path / "zero.npz"
    os.mkfifo(fifo)
    zero.symlink_to("/dev/zero")
    skeleton = tmp_path / "raw" / "s01s02" / "03" / "001" / "skeleton_pos.txt"  # a raw SBU folder of one sequence
    skeleton.parent.mkdir(parents=True)
    os.mkfifo(skeleton)
    out = tmp_path / "out"
    gen = ["generate", "--label", "kicking=1"]
    cases = []
    for path, kind in ((fifo, "a FIFO (named pipe)"), (zero, "a character device")):
        cases += [
            ([*gen, "--leader", str(BVH), "--bvh-map", str(path), "--out", str(out / "a.npz")], kind),
            ([*gen, "--leader", str(path), "--out", str(out / "b.npz")], kind),
            ([*gen, "--sequence", "s01s02/03/001", "--data", str(path), "--out", str(out / "c.npz")], kind),
            (["data", "summary", "--data", str(path)], kind),
            (["train", "--data", str(path), "--out", str(out / "run")], kind),
            (["train", "--config", str(path), "--out", str(out / "run")], kind),
            (["evaluate", "--classifier-config", str(path), "--quiet"], kind),
        ]
    cases.append((["data", "summary", "--data", str(tmp_path / "raw")], f"{skeleton}: a FIFO (named pipe)"))
    results = run_cli_cases([argv for argv, _ in cases])
    problems = []
    for (argv, expected), result in zip(cases, results, strict=True):
        lines = result["err"].strip().splitlines()
        if result["rc"] != 2 or len(lines) != 1 or expected not in lines[0] or result["seconds"] > 10:
            problems.append(f"{' '.join(argv)}: rc {result['rc']} in {result['seconds']:.1f} s: {result['err'][-300:]!r}")
    assert not problems, "\n".join(problems)
    assert not out.exists()


def test_a_raw_sbu_folder_whose_only_file_is_bad_is_one_line(tmp_path, capsys):
    raw = tmp_path / "raw" / "s01s02" / "03" / "001"
    raw.mkdir(parents=True)
    (raw / "skeleton_pos.txt").write_text("not numbers\n")
    assert main(["data", "summary", "--data", str(tmp_path / "raw")]) == 2
    one_line_error(capsys, "skeleton_pos.txt:1")


# ---- one line, naming the file and the line or field ------------------------------------------------------------------
def _bvh_with(tmp_path: Path, name: str, change) -> Path:
    lines = BVH.read_text().splitlines()
    change(lines)
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _set_first_value(lines: list[str], column: int, value: str) -> None:
    row = lines.index("MOTION") + 3
    values = lines[row].split()
    values[column] = value
    lines[row] = " ".join(values)


def _frames(lines, value):
    lines[lines.index("MOTION") + 1] = f"Frames: {value}"


@pytest.mark.parametrize("change, expected", [
    (lambda lines: _frames(lines, "9" * 400), ":186: Frames: '999999999999999999999999999999'... is not an integer up to"),
    (lambda lines: lines.__setitem__(8, "\t\tCHANNELS ³ Zrotation Yrotation Xrotation"),
     ":9: CHANNELS of LHipJoint: a count followed by that many channel names"),
    (lambda lines: _set_first_value(lines, 3, "1e300"), ":188: a Zrotation of 1e+300 degrees; angles up to 1e+06"),
], ids=["frames 400 digits", "channels superscript three", "rotation 1e300"])
def test_hostile_bvh_is_one_line_naming_the_file_and_line(tmp_path, change, expected):
    from imm_model.data.bvh import read_bvh

    path = _bvh_with(tmp_path, "take.bvh", change)
    with pytest.raises(DataFormatError) as info:
        read_bvh(path)
    assert str(info.value).startswith(str(path)) and expected in str(info.value)


@pytest.mark.parametrize("base", [["imm"], {"name": "imm"}, ["imm-diffusion"]])
def test_a_config_whose_base_is_not_a_name_is_one_line(tmp_path, capsys, base):
    config = tmp_path / "recipe.json"
    config.write_text(json.dumps({"base": base}))
    assert main(["train", "--config", str(config), "--out", str(tmp_path / "run")]) == 2
    one_line_error(capsys, "recipe.json", "unknown base config")


def test_a_cache_folder_that_is_a_file_is_refused_before_anything_is_trained(tmp_path, capsys, monkeypatch):
    cache = tmp_path / "cache"
    cache.write_text("a file")
    monkeypatch.setenv("IMM_CACHE_DIR", str(cache / "below"))
    assert main(["evaluate", "--quiet"]) == 2
    one_line_error(capsys, f"IMM_CACHE_DIR {cache / 'below'}: {cache} is not a folder")


def test_a_usage_error_is_one_line(capsys):
    with pytest.raises(SystemExit) as info:
        main(["reproduce", "--seeds", "a,b", "--out", "rep"])
    assert info.value.code == 2
    one_line_error(capsys, "--seeds: expected comma-separated integers, not 'a,b'", "imm reproduce --help")


def test_control_characters_in_a_file_name_are_shown_escaped(tmp_path, capsys):
    name = "take\x1b[2J\nrm.bvh"
    assert main(["generate", "--leader", str(tmp_path / name), "--label", "kicking=1", "--out", str(tmp_path / "o.npz")]) == 2
    err = one_line_error(capsys, "take\\x1b[2J\\nrm.bvh: leader file not found")
    assert "\x1b" not in err


def test_a_batch_item_name_too_long_is_refused_before_anything_is_written(tmp_path, capsys):
    leaders, out = tmp_path / "leaders", tmp_path / "out"
    leaders.mkdir()
    shutil.copy(BVH, leaders / "a.bvh")  # written first, were the plan not checked
    shutil.copy(BVH, leaders / ("b" * 250 + ".bvh"))  # a legal name (254 bytes); its output's name is not
    assert main(["generate", "--leader", str(leaders), "--label", "kicking=1", "--out", str(out)]) == 2
    one_line_error(capsys, "a file name of 264 bytes; names up to 255 bytes", "bbbb.bvh")
    assert not out.exists()


def test_a_leader_folder_skips_only_this_commands_own_leader_copies(tmp_path):
    from imm_model.generate import leader_files

    for name in ("a.bvh", "take.leader.bvh", "x.bvh", "x.leader.bvh"):
        shutil.copy(BVH, tmp_path / name)
    assert [p.name for p in leader_files([tmp_path])] == ["a.bvh", "take.leader.bvh", "x.bvh"]


# ---- a checkpoint with absurd weights -------------------------------------------------------------------------------
@pytest.mark.parametrize("bundled", ["imm_sbu.safetensors", "imm_diffusion.safetensors"])
def test_weights_of_1e30_with_a_valid_digest_are_refused_at_load(tmp_path, bundled):
    import torch

    from imm_model.checkpoint import load_checkpoint, save_checkpoint
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DIR

    tensors, meta = load_checkpoint(SAMPLE_DIR / bundled)
    path = tmp_path / bundled
    save_checkpoint(path, {k: torch.full_like(v, 1e30) for k, v in tensors.items()}, meta)  # a fresh, matching digest
    with pytest.raises(CheckpointError) as info:
        ReactionModel.load(path)
    assert str(info.value).startswith(f"{path}: its follower to a bundled leader stands") and "\n" not in str(info.value)
    model = ReactionModel.load(SAMPLE_DIR / bundled)  # the bundled model passes, and comes back as it was loaded
    assert not model.raw and (not model.settings.seed or model.guidance.sample_steps > 1)


def test_the_output_check_leaves_the_models_results_unchanged(sample_data):
    from imm_model.families.output_check import check_model_outputs
    from imm_model.inference import ReactionModel

    model = ReactionModel.load(SAMPLE_DIFFUSION)
    leader = sample_data.canonical(3)[0]
    label = np.eye(len(model.class_names), dtype=np.float32)[:1]
    before = model.synthesize_batch_canonical([leader], label, [5])[0]
    check_model_outputs(model)
    np.testing.assert_array_equal(model.synthesize_batch_canonical([leader], label, [5])[0], before)


# ---- imm reproduce --------------------------------------------------------------------------------------------------
def test_backend_local_says_it_was_asked_for(capsys):
    pytest.importorskip("ray")
    from imm_model.reproduce.runner import Runner

    with Runner(None, max(1, os.cpu_count() or 1), "local"):
        pass
    err = capsys.readouterr().err
    assert "local processes (--backend local)" in err and "not installed" not in err


@pytest.mark.slow
def test_an_address_nothing_answers_at_is_refused_in_seconds(tmp_path):
    pytest.importorskip("ray")
    start = time.monotonic()
    run = subprocess.run([sys.executable, "-m", "imm_model.cli", "reproduce", "--folds", "s04", "--tables", "afd",
                          "--out", str(tmp_path / "rep"), "--address", "127.0.0.1:1"],
                         capture_output=True, text=True, timeout=120, env=ENV)
    assert run.returncode == 2 and time.monotonic() - start < 60
    lines = run.stderr.strip().splitlines()
    assert lines[-1].startswith("imm reproduce: error: --address 127.0.0.1:1: nothing answers there"), run.stderr[-2000:]


@pytest.mark.slow
def test_sigterm_ends_a_ray_backed_reproduce_cleanly(tmp_path):
    pytest.importorskip("ray")
    proc = subprocess.Popen([sys.executable, "-m", "imm_model.cli", "reproduce", "--folds", "s04", "--tables", "afd",
                             "--out", str(tmp_path / "rep"), "--epochs", "50", "--classifier-epochs", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=ENV | {"PYTHONUNBUFFERED": "1"})
    try:
        seen = []
        for line in proc.stdout:  # the jobs are on Ray once the evaluations are counted
            seen.append(line)
            if "evaluations:" in line:
                break
        assert any("running on a local Ray" in line for line in seen), "".join(seen)
        proc.send_signal(signal.SIGTERM)
        start = time.monotonic()
        rest, _ = proc.communicate(timeout=60)
        seconds = time.monotonic() - start
    finally:
        proc.kill()
    output = "".join(seen) + rest
    assert proc.returncode == 130 and "SIGTERM received" not in output and "Traceback" not in output, output[-3000:]
    assert output.strip().splitlines()[-1].endswith("imm reproduce: interrupted")
    assert seconds < 30, seconds  # within 5 s on an idle machine; generous for a busy one


def test_the_input_check_refuses_fifos_devices_and_links_to_them_without_opening_them(tmp_path):
    from imm_model.inputs import check_input, read_input

    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "zero").symlink_to("/dev/zero")
    for name, kind in (("pipe", "a FIFO (named pipe)"), ("zero", "a character device")):
        for reader in (check_input, lambda path, what: read_input(path, what, 1000)):
            with pytest.raises(DataFormatError) as info:
                reader(tmp_path / name, "leader file")
            assert f"{name}: {kind}, not a regular file (leader file expected)" in str(info.value).replace(
                " (a link to /dev/zero)", "")
    (tmp_path / "big").write_bytes(b"x" * 1001)
    with pytest.raises(DataFormatError, match=r"big: 0.0 MB; leader files up to 0 MB are read"):
        read_input(tmp_path / "big", "leader file", 1000)
    assert read_input(BVH, "leader file", 10**6) == BVH.read_bytes()


# ---- labels, judges and files that are not what they claim ----------------------------------------------------------
@pytest.mark.parametrize("label, words", [
    ("kicking=1,upper:kicking=-1,lower:kicking=-1", "kicking is given for the whole body and then for both parts apart"),
    ("upper:", "'upper:' is not a label item: write class=value, upper:class=value or lower:class=value"),
    ("upper:kicking:1", "'upper:kicking:1' is not a label item"),
    ("kicking=1,kicking=-1", "gives kicking twice"),
    ("kickin", "unknown class 'kickin'"),
])
def test_a_label_that_contradicts_itself_or_is_misspelled_is_one_line_naming_the_spelling(tmp_path, capsys, label, words):
    assert main(["generate", "--leader", str(BVH), "--label", label, "--out", str(tmp_path / "x.npz")]) == 2
    one_line_error(capsys, words)
    assert not (tmp_path / "x.npz").exists()


def test_a_classifier_given_as_a_model_is_named_as_such(tmp_path, capsys):
    from imm_model.paths import SAMPLE_JUDGE

    assert main(["generate", "--leader", str(BVH), "--label", "kicking=1", "--checkpoint", str(SAMPLE_JUDGE),
                 "--out", str(tmp_path / "x.npz")]) == 2
    one_line_error(capsys, "follower_judge.safetensors: a reaction classifier (a 'reads as' judge), not a reaction model")


def test_a_lower_body_judge_is_refused_for_a_skeleton_without_legs(tmp_path, capsys):
    """Its view would hold the body centre alone: a 'lower-body' judge that reads no leg."""
    from dataclasses import replace

    from imm_model.data.dataset import InteractionDataset

    data = InteractionDataset.load(SAMPLE_DATA)
    legless = replace(data.skeleton, name="legless",
                      body_parts={k: v for k, v in data.skeleton.body_parts.items() if not k.endswith("leg")})
    replace(data, skeleton=legless).save(tmp_path / "legless.npz")
    assert main(["data", "build-judge", "--inputs", "lower", "--data", str(tmp_path / "legless.npz"),
                 "--out", str(tmp_path / "lower.safetensors")]) == 2
    one_line_error(capsys, "legless.npz: its legless skeleton names no legs", "a lower-body judge would read none")
    assert not (tmp_path / "lower.safetensors").exists()

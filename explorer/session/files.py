"""The session's synthesized interaction as files a user downloads: .npz and .bvh bytes and their names."""

from __future__ import annotations

from pathlib import Path

FPS = 15.0  # SBU's frame rate


class SessionFiles:
    def __init__(self, session) -> None:  # the Session (session.py) it is a room of
        self.session = session

    def npz(self) -> bytes:
        """The synthesized interaction as an .npz file's bytes (imm_model/interaction_file.py, docs/formats.md)."""
        from imm_model.interaction_file import interaction_arrays, interaction_bytes

        ses = self.session
        ses.settle()  # a file holds the model's own reaction, never a slider's draft
        path = getattr(ses.model, "path", None)
        return interaction_bytes(interaction_arrays(
            ses.world(ses.leader), ses.world(ses.synth), ses.frame, ses.data.skeleton,
            class_names=ses.class_names, label=ses.vector, scale=ses.scale, checkpoint=Path(path).name if path else "",
            fps=FPS, ground_truth=None if ses.ground_truth is None else ses.world(ses.ground_truth),
            sequence_id=None if ses.upload else ses.data.sequence_ids[ses.index],
            live=(ses.live.made, ses.live.steered) if ses.live.on else None, **ses.model.provenance(ses.seed)))

    def bvh(self, character: str = "follower") -> bytes:
        """The synthesized follower (or the leader) as a BVH file's bytes, world metres (imm_model/data/bvh.py)."""
        import tempfile

        from imm_model.data.bvh import write_bvh

        ses = self.session
        ses.settle()
        motion = ses.world(ses.synth if character == "follower" else ses.leader)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "x.bvh"
            write_bvh(path, motion, ses.data.skeleton, FPS)
            return path.read_bytes()

    def name(self, ext: str) -> str:
        """The sequence's id (or the uploaded file's stem) and the mix: `s01s02-03-001_kicking+1.npz`."""
        ses = self.session
        sid = Path(ses.upload.name).stem if ses.upload else ses.data.sequence_ids[ses.index].replace("/", "-")
        mix = "_".join(f"{k}{w:+g}" for k, w in ses.label.keys().items()) or "neutral"
        return f"{sid}_{mix}.{ext}"

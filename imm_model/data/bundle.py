"""Building the bundled sample file and summarizing any dataset."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from imm_model.data.dataset import InteractionDataset
from imm_model.data.k3hi import load_k3hi
from imm_model.data.loading import LoadResult
from imm_model.data.sbu import PAPER_CLASSES, load_sbu
from imm_model.data.splits import subjects_of
from imm_model.errors import DataFormatError

# The bundled model is trained with this subject held out (fold loso-s04: 49 of 197 sequences).
BUNDLED_HELD_OUT_SUBJECT = "s04"

SBU_CITATION = (
    "Kiwon Yun, Jean Honorio, Debaleena Chattopadhyay, Tamara L. Berg, Dimitris Samaras. "
    "Two-person Interaction Detection Using Body-Pose Features and Multiple Instance Learning. "
    "HAU3D workshop, CVPR 2012."
)


def build_sbu_bundle(raw_root: Path, held_out_subject: str = BUNDLED_HELD_OUT_SUBJECT) -> InteractionDataset:
    """Raw SBU folder -> the 6-class, 197-sequence canonical dataset (strict: no file may be bad)."""
    result = load_sbu(raw_root, classes="paper", leader="actor", strict=True)
    data = InteractionDataset.from_interactions(
        result.interactions,
        class_names=PAPER_CLASSES,
        info={
            "source": "SBU Kinect Interaction v2.0 (clean skeletons), see sample_data/README.md",
            "citation": SBU_CITATION,
            "terms": "research use only; cite the paper above; do not redistribute outside the project",
            "units": "metres, canonical frame of the leader (A); world = to_world(yaw, origin)",
            "held_out_subject": held_out_subject,
        },
    )
    data.held_out = np.array([held_out_subject in subjects_of(p) for p in data.subject_pairs])
    return data


def load_any(path: Path | str) -> InteractionDataset | LoadResult:
    """A bundle (.npz), a raw SBU folder or a K3HI folder, told apart by what is inside."""
    path = Path(path)
    if path.suffix == ".npz" or (path.exists() and not path.is_dir()):  # a FIFO or device: refused by the reader
        return InteractionDataset.load(path)
    if (path / "Skeletons").is_dir():
        return load_k3hi(path)
    if path.is_dir():
        return load_sbu(path, classes="all")
    raise DataFormatError(f"{path}: no such file or folder")


def summary_table(source: InteractionDataset | LoadResult) -> str:
    """Per-class sequence counts, frame lengths and subjects, as a fixed-width text table."""
    if isinstance(source, InteractionDataset):
        rows = [
            (source.action_name(i), int(source.lengths[i]), source.subject_pairs[i], bool(source.held_out[i]))
            for i in range(len(source))
        ]
        class_names = source.class_names
    else:
        rows = [(it.action, it.num_frames, it.subject_pair, False) for it in source.interactions]
        class_names = source.class_names
    counts = Counter(r[0] for r in rows)
    head = f"{'class':<20}{'sequences':>10}{'frames':>8}{'min len':>8}{'mean len':>9}{'max len':>8}  subjects"
    lines = [head, "-" * len(head)]
    for name in class_names:
        lens = [r[1] for r in rows if r[0] == name]
        if not lens:
            lines.append(f"{name:<20}{0:>10}")
            continue
        subjects = sorted({s for r in rows if r[0] == name and r[2] for s in subjects_of(r[2])})
        lines.append(
            f"{name:<20}{counts[name]:>10}{sum(lens):>8}{min(lens):>8}{np.mean(lens):>9.1f}{max(lens):>8}  {' '.join(subjects) or '-'}"
        )
    lens = [r[1] for r in rows]
    lines.append("-" * len(head))
    lines.append(f"{'total':<20}{len(rows):>10}{sum(lens):>8}{min(lens):>8}{np.mean(lens):>9.1f}{max(lens):>8}")
    held = sum(r[3] for r in rows)
    if held:
        lines.append(f"{held} sequences are held out from the bundled model's training")
    return "\n".join(lines)

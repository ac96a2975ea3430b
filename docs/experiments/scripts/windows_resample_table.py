"""One fold's LOSO figures of a clip sampled whole beside the same clips made as a long take is (in windows), each
window's steps taken once or resampled: the rows online_fold.py wrote in one run of the same judges.

    python docs/experiments/scripts/online_fold.py --checkpoint sample_data/imm_diffusion.safetensors --fold s04 \\
        --modes windows --out docs/experiments/data/long-takes-resample-loso.jsonl                  # RESAMPLE as shipped
    python docs/experiments/scripts/online_fold.py --checkpoint sample_data/imm_diffusion.safetensors --fold s04 \\
        --modes offline windows --set RESAMPLE=0 --out docs/experiments/data/long-takes-resample-loso.jsonl
    python docs/experiments/scripts/windows_resample_table.py docs/experiments/data/long-takes-resample-loso.jsonl
"""

from __future__ import annotations

import argparse
import json

FIGURES = (("afd", "AFD"), ("afd_best_of_5", "best of 5"), ("fid", "FID"), ("off_label", "off-label"),
           ("interior_limb_speed_ratio", "limbs between the ends / real"), ("jitter_ratio", "jitter / real"),
           ("foot_skate_mps", "foot skate (m/s)"), ("multimodality_m", "variations (m)"))


def name(row: dict) -> str:
    if row["mode"] == "offline":
        return "the clip sampled whole"
    resample = row.get("settings", {}).get("RESAMPLE", 0)
    return "in windows, each step once" if not resample else f"in windows, each step {resample} more times"


def cell(value) -> str:
    return "-".join(f"{v:.2f}" for v in value) if isinstance(value, list) else f"{value:.3f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", help="online_fold.py output (JSON lines) of one fold")
    args = ap.parse_args()
    rows = sorted((json.loads(line) for line in open(args.rows) if line.strip()), key=lambda r: (r["mode"] != "offline", name(r)))
    print(f"| {rows[0]['fold']} | " + " | ".join(label for _, label in FIGURES) + " |")
    print("|---|" + "---:|" * len(FIGURES))
    for row in rows:
        print(f"| {name(row)} | " + " | ".join(cell(row[key]) for key, _ in FIGURES) + " |")


if __name__ == "__main__":
    main()

"""curves.png of a training run: losses and validation AFD per epoch, the selected epoch marked."""

from __future__ import annotations

from pathlib import Path


def plot_curves(history: list[dict], best_epoch: int, subject: str | None, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not history:
        return
    ep = [r["epoch"] for r in history]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for key in ("l1", "cont", "adv", "critic", "d_loss"):
        if any(r.get(key) for r in history):
            axes[0].plot(ep, [r.get(key, 0.0) for r in history], label=key)
    axes[0].set_yscale("log")
    axes[0].set_title("training losses")
    axes[0].legend()
    axes[1].plot(ep, [r["val_afd_m"] for r in history], label="validation AFD (m)")
    axes[1].axvline(best_epoch, color="k", ls=":", label=f"best epoch {best_epoch}")
    axes[1].set_title(f"validation ({subject or 'all'} held out)")
    axes[1].legend()
    for ax in axes:
        ax.set_xlabel("epoch")
    fig.tight_layout()
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=80)
    plt.close(fig)
    tmp.replace(path)

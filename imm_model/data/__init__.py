"""Data layer: raw readers (SBU, K3HI), leader choice, canonical frame, splits, batches, bundle."""

from imm_model.data.canonical import CanonicalFrame, facing_direction
from imm_model.data.dataset import InteractionDataset
from imm_model.data.k3hi import K3HI_CLASSES, load_k3hi
from imm_model.data.loading import LoadResult
from imm_model.data.sbu import ALL_CLASSES, PAPER_CLASSES, load_sbu, metres_to_normalized, normalized_to_metres
from imm_model.data.sequence import Interaction
from imm_model.data.splits import Fold, five_folds, loso_fold, loso_folds, validation_split

__all__ = [
    "ALL_CLASSES", "PAPER_CLASSES", "K3HI_CLASSES", "CanonicalFrame", "Fold", "Interaction",
    "InteractionDataset", "LoadResult", "facing_direction", "five_folds", "load_k3hi", "load_sbu",
    "loso_fold", "loso_folds", "metres_to_normalized", "normalized_to_metres", "validation_split",
]

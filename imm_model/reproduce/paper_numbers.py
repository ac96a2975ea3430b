"""The numbers the paper reports (Goel, Men, Ho, CGF 2022; its LaTeX source, ../shared/paper/), copied from
its tables so the report can print them beside ours. Class order: SBU's (kicking ... punching)."""

from __future__ import annotations

# Table "AFD of different actions in the SBU dataset" (tab:SBU_AFD): method -> per-class AFD.
AFD_METHODS = ("NN", "HMM", "Kitani et al. 2012", "Huang & Kitani 2014", "Huang et al. 2015", "Men et al. 2022", "IMM (paper)")
AFD = {
    "NN": (0.81, 0.51, 0.48, 0.61, 0.63, 0.56),
    "HMM": (0.92, 0.60, 1.41, 0.67, 3.84, 0.66),
    "Kitani et al. 2012": (0.65, 0.45, 0.42, 0.48, 0.53, 0.48),
    "Huang & Kitani 2014": (0.92, 0.61, 0.54, 0.81, 0.74, 0.66),
    "Huang et al. 2015": (0.67, 0.48, 0.42, 0.47, 0.54, 0.52),
    "Men et al. 2022": (0.53, 0.52, 0.44, 0.72, 0.45, 0.45),
    "IMM (paper)": (0.50, 0.43, 0.40, 0.42, 0.40, 0.32),
}

# Table "FID of different actions in the SBU dataset" (tab:FID_SBU).
FID_SBU = {
    "Men et al. 2022": (10.8, 20.8, 23.8, 29.5, 16.7, 11.2),
    "IMM (paper)": (9.3, 16.8, 15.1, 19.3, 11.7, 10.8),
}

# Table "FID ... in the 2C dataset" (tab:FID_2C): kick, punch. 2C is not public; K3HI stands in (docs/reproduction.md).
FID_2C = {"Men et al. 2022": (194.2, 148.1), "IMM (paper)": (164.2, 122.4)}

# Table "Ablations ... evaluated by AFD on the SBU dataset" (tab:ablation_AFD): our recipe name -> the paper's row.
ABLATION_AFD = {
    "imm": ("OURS", (0.5, 0.43, 0.4, 0.42, 0.4, 0.32)),
    "imm-no-d": ("OURS w/o D", (0.53, 0.45, 0.42, 0.49, 0.44, 0.38)),
    "imm-no-bone": ("OURS w/o L_b", (0.45, 0.42, 0.39, 0.40, 0.39, 0.32)),
    "imm-no-continuity": ("OURS w/o L_c", (0.59, 0.45, 0.55, 0.46, 0.41, 0.4)),
    "imm-no-fc": ("OURS w/o FC", (0.55, 0.47, 0.46, 0.49, 0.41, 0.4)),
    "imm-no-label": ("OURS w/o Multi-Hot Embed", (0.51, 0.48, 0.50, 0.66, 0.46, 0.45)),
}

# Table "Accuracy of the classifier on different splits" (tab:recognition): 99/98 and 124/123 sequences.
RECOGNITION = {
    "Original": (0.9474, 0.9411, 0.6923, 0.5385, 0.6674, 0.8889),
    "Augmented": (0.9960, 0.8770, 0.7056, 0.6407, 0.8813, 0.9112),
}

# Where the paper's text and the authors' public code disagree, and what this project does (docs/reproduction.md).
DISAGREEMENTS = (
    ("AFD", "the mean per-frame Euclidean distance between poses", "squares the distance",
     "reports both: `afd` (text) is the headline, `afd_squared` (code) beside it"),
    ("Model selection", "not stated", "keeps the epoch with the best AFD on the test fold",
     "selects on a validation split carved from the training subjects; the test fold is never seen"),
    ("L1 term", "L1 between poses, weight 1", "sums L1 over batch x frames x coordinates, so the adversarial "
     "weight 1 is ~1e-4 of it", "`imm` averages; `--config paper` sums, as the code does"),
    ("Label input", "the multi-hot label is joined to the whole-body stream", "the label is its own stream",
     "joins it to the whole-body stream, as the text says"),
    ("Attention query", "the decoder's previous state (Eq. 3)", "-",
     "`imm` queries with the frame's own encoding (all frames at once); `--config paper` uses Eq. 3"),
    ("Epochs on SBU", "1600", "-", "`paper`: 1600; `imm`: early stopping on validation AFD (about 70 epochs)"),
)

"""Networks every family shares: the reaction classifiers (the evaluation's judges, the studio's "reads as", the GAN's
label critic) and their numpy runtime. Each model family's own networks live in its folder under families/."""

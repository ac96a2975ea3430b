"""`imm reproduce`: the paper's tables from one command, every training run a Ray task (docs/reproduction.md)."""

"""Training: recipes (config), losses, augmentation, the loop, and the `imm train` command."""

"""IMM Studio: a trame web app to explore the reaction model (see docs/user-guide.md and docs/architecture.md).

The library (`imm_model`) never imports this package; `imm explore` reaches it through the
`imm.commands` entry point.
"""

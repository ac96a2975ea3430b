"""IMM Studio: a trame web app to explore the reaction model (see docs/explorer.md).

The library (`imm_model`) never imports this package; `imm explore` reaches it through the
`imm.commands` entry point.
"""

"""IMM Studio's library: an implementation of "Interaction Mix and Match" (Goel, Men, Ho).

data -> model -> training -> evaluation; `explorer/` (the web studio) builds on top of it.
"""

__version__ = "0.1.0"

"""Tools for the project's developers: generated docs and structure checks, not used at run time."""

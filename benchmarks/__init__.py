"""One-off investigations of hairlut, each a module run from the repository's root as ``python -m benchmarks.NAME``.

What ``hairlut bench`` measures lives in ``hairlut.bench``; the modules here are the studies it does not run (see
README.md, which dates each).  They share :mod:`benchmarks._common` and ``hairlut.bench``'s public helpers.
"""

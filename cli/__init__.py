"""The ``hairlut`` command line (import name ``hairlut_cli``): parses, calls hairlut, prints."""

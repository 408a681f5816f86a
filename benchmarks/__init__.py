"""silpose benchmarks: one module per section, outside the installed packages (see README.md here).

Run from the repository root: ``python -m benchmarks.run [--quick] [--only SECTIONS]`` (``just bench``).
"""

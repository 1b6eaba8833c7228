"""The L-system stage: grammar text to a derived module string.

``grammar`` parses (native files through ``dialects/``), ``expr`` evaluates the grammar's expressions,
``derive`` rewrites the axiom into a ``ModuleString`` (``modules``), ``presets`` holds the bundled grammars
and ``diagnostics`` names what a grammar holds that will not be drawn as meant.
"""

"""pma-model, the command line: the parser and entry point (:mod:`.main`), one module per command
group.
"""

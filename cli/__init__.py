"""The ``wncs`` command line (:mod:`cli.main`): the top layer, above the application."""

"""Sub-commands of the ``pneusim`` command line, one module each."""

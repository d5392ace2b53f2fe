"""Online half of the vision interface (Lee et al. §5.3), and the ``mimic`` command line."""

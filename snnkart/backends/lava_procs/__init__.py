"""snnkart's custom Lava process: the host bridge. Lava's compiler executes every module in the
directory of a custom process to find its models, so this package holds nothing else."""

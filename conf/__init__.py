"""The Hydra configs as package data: an installed gbgrowth has this folder as the package
gbgrowth_conf (pyproject.toml), which the stages find through Hydra's package search path
(pkg://gbgrowth_conf); a checkout reads the folder itself. No code: Hydra needs the file to take
the folder for a package."""

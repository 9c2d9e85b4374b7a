"""The package version, in a module of its own: a stage that records which ctrkin wrote a file
(datasets, model folders, results) imports this leaf, not the package root above every stage."""

__version__ = "0.2.0"   # semantic versioning: CONTRIBUTING.md; pyproject.toml reads it

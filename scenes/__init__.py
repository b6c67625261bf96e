"""The scenes, sweeps, tuning files and rule bases, shipped as the resource package
`bwr_twin.scenes` (see pyproject.toml).

This file holds no code. It makes the folder a regular package: an editable install maps a
package to a folder outside its parent's only when the package has an `__init__.py` (a
namespace package there is not found through its parent's path), and `importlib.resources`
gives a regular package's folder as a plain path.
"""

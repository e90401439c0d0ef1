"""Give notebooks the standard ``python3`` kernelspec (used after creating a notebook with jupytext).

    python tools/set_kernelspec.py notebooks/NN_name.ipynb [...]
"""
import sys

import nbformat

for path in sys.argv[1:]:
    nb = nbformat.read(path, as_version=4)
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    nb.metadata.pop("jupytext", None)
    nbformat.write(nb, path)
    print(f"kernelspec set: {path}")

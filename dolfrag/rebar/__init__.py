"""Reinforcing bars: the bars as elastic-plastic cables tied to the cells they cross
(cables.py), where a generated geometry puts them (layout.py), and the layers behind the
face groups of a mesh file (faces.py)."""

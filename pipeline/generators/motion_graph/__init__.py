"""The motion graph family (seed 002, Yang, Yang & Hodgins): a graph of the real train walks' frames
(``graph.py``), searched for plan rows (``search.py``) and blended and placed as gaits (``family.py``)."""

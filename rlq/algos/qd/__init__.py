"""Quality-diversity pieces shared by MAP-Elites and random search: the grid archive and its
metrics (archive.py), variation operators (variation.py), fitness and descriptor measures
(measures.py) and the archive heatmap (heatmap.py)."""

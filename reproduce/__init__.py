"""Reproductions of the source papers' experiments, one module per paper (``sensorgym reproduce``)."""

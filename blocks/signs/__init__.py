"""Door signs: the paper's textual sign detector, reader and sign labeling/correlation.

The algorithms are plain functions here (``detect``, ``read``, ``text``,
``geometry``, ``correlate``, ``seek``); ``blocks.signs.blocks`` adapts them to the
dataflow.
"""

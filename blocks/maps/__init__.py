"""Occupancy mapping: the paper's 2-bit online map, a log-odds map, tiles, map files, scores.

The algorithms are plain functions and small classes here; ``blocks.maps.blocks``
adapts them to the dataflow.
"""

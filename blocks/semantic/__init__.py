"""Semantic blocks: the knowledge base and the semantic map as dataflow nodes
(thin adapters over the :mod:`semantic` package)."""

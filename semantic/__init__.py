"""semantic: indoor ontology, reasoner and semantic map (see issue 7)."""

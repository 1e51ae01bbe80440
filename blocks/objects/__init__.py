"""Object blocks: the object recogniser as a dataflow block (see semantic.recognise)."""

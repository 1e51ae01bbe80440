"""The semmap dataflow engine: domain-free."""
from .block import Block, RunContext
from .errors import BlockError, GraphError, ParamError, SchemaViolation, SemmapError
from .loader import load_graph, parse_overrides
from .model import Endpoint, FlatGraph, FlatNode
from .params import Param
from .probes import load_probes
from .registry import REGISTRY, block
from .runner import BlockFailure, Runner
from .schema import Port
from .validate import check_graph, schedule

__all__ = [
    "Block", "BlockError", "BlockFailure", "Endpoint", "FlatGraph", "FlatNode", "GraphError",
    "Param", "ParamError", "Port", "REGISTRY", "RunContext", "Runner", "SchemaViolation",
    "SemmapError", "block",
    "check_graph", "load_graph", "load_probes", "parse_overrides", "schedule",
]

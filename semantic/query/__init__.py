"""The text query planner: English commands and questions to objectives and plans.

:func:`parse_command` turns "fetch the manager's mail" into a :class:`Request`
(action, object, owner, destination, source, time) using the grammar in
``grammar.lark`` and the ontology's lexicon (:mod:`semantic.lexicon`).
"""
from __future__ import annotations

from semantic.query.parse import ACTIONS, Mention, ParseError, Request, parse_command

__all__ = ["ACTIONS", "Mention", "ParseError", "Request", "parse_command"]

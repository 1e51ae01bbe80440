"""The text query planner: English commands and questions to objectives and plans.

:func:`ask` runs the three stages: :func:`parse_command` turns "fetch the
manager's mail" into a :class:`Request` (grammar in ``grammar.lark``, words from
the ontology's lexicon); :func:`ground` places its things and people on a map
through the reasoner (:class:`Grounding`); :func:`plan_task` orders the steps
and plans each leg with A* (:class:`TaskPlan`). Maps come from
:func:`load_map`: a semantic mapping run's folder, or a world surveyed.
"""
from __future__ import annotations

from semantic.query.ground import Grounding, GroundingError, Objective, Target, ground
from semantic.query.mapsource import MapSourceError, QueryMap, load_map, load_run_map, survey_map
from semantic.query.parse import ACTIONS, Mention, ParseError, Request, parse_command
from semantic.query.session import ask, parse_now
from semantic.query.tasks import Step, TaskPlan, plan_task

__all__ = ["ACTIONS", "Grounding", "GroundingError", "MapSourceError", "Mention", "Objective",
           "ParseError", "QueryMap", "Request", "Step", "Target", "TaskPlan", "ask", "ground",
           "load_map", "load_run_map", "parse_command", "parse_now", "plan_task", "survey_map"]

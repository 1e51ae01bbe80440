"""Fuzzy inference: knowledge bases in YAML, skfuzzy as the reference, a compiled evaluator.

``load_kb`` reads a knowledge base (variables, trapezoidal terms, rules);
``build_skfuzzy`` turns it into a scikit-fuzzy ControlSystem, the oracle; and
``compile_kb`` turns it into a vectorised Mamdani evaluator that gives the
same answers thousands of times faster, for one robot or a batch.
"""
from .compiled import CompiledController, compile_kb
from .kb import KnowledgeBase, Rule, Term, Variable, load_kb

__all__ = ["CompiledController", "KnowledgeBase", "Rule", "Term", "Variable", "compile_kb",
           "load_kb"]

"""``semmap sparql``: query a run's semantic map with SPARQL (registered under ``semmap.commands``)."""
from __future__ import annotations

import json
from pathlib import Path

import click

from blocks.core.errors import SemmapError

#: Prefixes every query may use without declaring them.
PREFIXES = {
    "indoor": "https://w3id.org/semmap/indoor#",
    "map": "https://w3id.org/semmap/map#",
    "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#",
    "rdfs": "http://www.w3.org/2000/01/rdf-schema#",
    "owl": "http://www.w3.org/2002/07/owl#",
    "skos": "http://www.w3.org/2004/02/skos/core#",
    "xsd": "http://www.w3.org/2001/XMLSchema#",
}


class QueryError(SemmapError):
    """A SPARQL query or the semantic map it runs on is unusable (a user error)."""


def semantic_map_file(run_or_file: str | Path) -> Path:
    """The ``semantic_map.ttl`` of a run folder (or the file itself)."""
    path = Path(run_or_file)
    ttl = path / "semantic_map.ttl" if path.is_dir() else path
    if not ttl.is_file():
        raise QueryError(f"there is no semantic map at {ttl}. Run a semantic mapping graph "
                         "first, e.g. `semmap run graphs/semantic_mapping.yaml --out runs/office`, "
                         "then pass its output folder (runs/office).")
    return ttl


def run_query(ttl: Path, query: str) -> tuple[list[str], list[list[str]]]:
    """Run a SELECT or ASK query on a semantic map file.

    Parameters
    ----------
    ttl
        The semantic map in Turtle.
    query
        SPARQL; the prefixes of :data:`PREFIXES` are predeclared.

    Returns
    -------
    header, rows
        Column names and rows of strings (ASK gives one column ``answer``).
    """
    import rdflib
    graph = rdflib.Graph()
    try:
        graph.parse(ttl, format="turtle")
    except Exception as exc:  # rdflib raises several parser error types
        raise QueryError(f"{ttl} is not valid Turtle ({exc}). Write it again with a semantic "
                         "mapping run.", file=ttl) from None
    for prefix, iri in PREFIXES.items():
        graph.bind(prefix, iri, override=False)
    try:
        result = graph.query(query, initNs=PREFIXES)
    except Exception as exc:  # pyparsing and rdflib errors for a malformed query
        raise QueryError(f"the SPARQL query could not be run: {exc}. Check its syntax; the "
                         f"prefixes {', '.join(sorted(PREFIXES))} are predeclared.") from None
    if result.type == "ASK":
        return ["answer"], [[str(bool(result.askAnswer)).lower()]]
    if result.type != "SELECT":
        raise QueryError("only SELECT and ASK queries are answered; for CONSTRUCT, load "
                         f"{ttl} in rdflib yourself.")
    header = [str(v) for v in result.vars]
    rows = [[_short(value, graph) for value in row] for row in result]
    return header, rows


def _short(value, graph) -> str:
    """An IRI as prefix:name when a known prefix covers it; literals as their text."""
    if value is None:
        return ""
    import rdflib
    if isinstance(value, rdflib.URIRef):
        try:
            return graph.namespace_manager.normalizeUri(value)
        except Exception:
            return str(value)
    return str(value)


@click.command(name="sparql")
@click.argument("run", metavar="RUN_DIR")
@click.argument("query", metavar="QUERY")
@click.option("--json", "as_json", is_flag=True, help="Print {header, rows} as JSON.")
def sparql(run: str, query: str, as_json: bool) -> None:
    """Answer a SPARQL SELECT/ASK QUERY (text or @FILE) over RUN_DIR/semantic_map.ttl.

    The prefixes indoor:, map:, rdf:, rdfs:, owl:, skos: and xsd: are predeclared, e.g.

        semmap sparql runs/demo "SELECT ?p ?e WHERE { ?p indoor:hasDefaultEquipment ?e }"
    """
    if query.startswith("@"):
        qfile = Path(query[1:])
        if not qfile.is_file():
            raise QueryError(f"the query file {qfile} does not exist. Pass the query text, "
                             "or @FILE naming a file that holds it.")
        query = qfile.read_text()
    header, rows = run_query(semantic_map_file(run), query)
    if as_json:
        click.echo(json.dumps({"header": header, "rows": rows}, indent=2))
        return
    widths = [max([len(h)] + [len(r[i]) for r in rows]) for i, h in enumerate(header)]
    click.echo("  ".join(h.ljust(w) for h, w in zip(header, widths)))
    click.echo("  ".join("-" * w for w in widths))
    for row in rows:
        click.echo("  ".join(v.ljust(w) for v, w in zip(row, widths)))
    click.echo(f"({len(rows)} row{'s' if len(rows) != 1 else ''})")

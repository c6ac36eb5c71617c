#!/usr/bin/env python3
"""Checks that a file (or stdin) is a GeoJSON FeatureCollection as RFC 7946 defines it, with
Python's own json module (a parser independent of the one fleetgw writes with).

Strict where RFC 7946 and RFC 8259 are: no NaN/Infinity, no duplicate member names, a
FeatureCollection of Features, each with a geometry that is null or a Point / LineString /
MultiLineString / Polygon... with valid positions ([longitude, latitude], in range; a
LineString of two or more positions), properties an object or null, an id a string or a number,
no "crs" member (removed by RFC 7946). Prints a summary as one JSON object on stdout:
{"features": N, "geometry_types": {"LineString": n, ...}, "null_geometries": n,
 "linestring_points": [..], "ids": [..]}; exits 1 naming the first problem and where.
"""
import json
import math
import sys


class Invalid(Exception):
    pass


def no_duplicates(pairs):
    seen = {}
    for key, value in pairs:
        if key in seen:
            raise Invalid(f"duplicate member name {key!r}")
        seen[key] = value
    return seen


def reject_constant(name):
    raise Invalid(f"{name} is not JSON (RFC 8259)")


def position(p, where):
    if not isinstance(p, list) or len(p) < 2 or len(p) > 3:
        raise Invalid(f"{where}: a position is an array of 2 or 3 numbers, got {p!r}")
    for x in p:
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise Invalid(f"{where}: not a number: {x!r}")
    if not -180 <= p[0] <= 180:
        raise Invalid(f"{where}: longitude {p[0]} outside -180..180 (RFC 7946: longitude first)")
    if not -90 <= p[1] <= 90:
        raise Invalid(f"{where}: latitude {p[1]} outside -90..90")


def positions(ps, where, minimum):
    if not isinstance(ps, list) or len(ps) < minimum:
        raise Invalid(f"{where}: needs an array of at least {minimum} positions")
    for i, p in enumerate(ps):
        position(p, f"{where}[{i}]")


def geometry(g, where):
    if g is None:
        return None
    if not isinstance(g, dict) or "type" not in g:
        raise Invalid(f"{where}: a geometry is null or an object with a type")
    t = g["type"]
    if t == "GeometryCollection":
        for i, sub in enumerate(g.get("geometries", [])):
            geometry(sub, f"{where}.geometries[{i}]")
        return t
    if "coordinates" not in g:
        raise Invalid(f"{where}: {t} without coordinates")
    c = g["coordinates"]
    if t == "Point":
        position(c, f"{where}.coordinates")
    elif t in ("LineString", "MultiPoint"):
        positions(c, f"{where}.coordinates", 2 if t == "LineString" else 0)
    elif t in ("MultiLineString", "Polygon"):
        for i, part in enumerate(c):
            positions(part, f"{where}.coordinates[{i}]", 2 if t == "MultiLineString" else 4)
    elif t == "MultiPolygon":
        for i, poly in enumerate(c):
            for j, ring in enumerate(poly):
                positions(ring, f"{where}.coordinates[{i}][{j}]", 4)
    else:
        raise Invalid(f"{where}: unknown geometry type {t!r}")
    return t


def check(doc):
    if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection":
        raise Invalid("top level: not an object of type FeatureCollection")
    if "crs" in doc:
        raise Invalid("top level: 'crs' is not GeoJSON since RFC 7946")
    features = doc.get("features")
    if not isinstance(features, list):
        raise Invalid("top level: 'features' is not an array")
    summary = {"features": len(features), "geometry_types": {}, "null_geometries": 0,
               "linestring_points": [], "ids": []}
    for i, f in enumerate(features):
        where = f"features[{i}]"
        if not isinstance(f, dict) or f.get("type") != "Feature":
            raise Invalid(f"{where}: not an object of type Feature")
        if "geometry" not in f:
            raise Invalid(f"{where}: no 'geometry' member (null is allowed, absent is not)")
        if "properties" not in f or not (f["properties"] is None or isinstance(f["properties"], dict)):
            raise Invalid(f"{where}: 'properties' must be an object or null")
        if "id" in f and (isinstance(f["id"], bool) or not isinstance(f["id"], (str, int, float))):
            raise Invalid(f"{where}: 'id' must be a string or a number")
        t = geometry(f["geometry"], f"{where}.geometry")
        if t is None:
            summary["null_geometries"] += 1
        else:
            summary["geometry_types"][t] = summary["geometry_types"].get(t, 0) + 1
        summary["linestring_points"].append(
            len(f["geometry"]["coordinates"]) if t == "LineString" else 0)
        summary["ids"].append(f.get("id"))
    return summary


def main():
    text = open(sys.argv[1], encoding="utf-8").read() if len(sys.argv) > 1 else sys.stdin.read()
    try:
        doc = json.loads(text, object_pairs_hook=no_duplicates, parse_constant=reject_constant)
        print(json.dumps(check(doc)))
    except (Invalid, json.JSONDecodeError) as e:
        print(f"invalid GeoJSON: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

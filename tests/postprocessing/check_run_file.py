#!/usr/bin/python3
"""Checks a rubble run file against docs/output-format.md and against the values the writer was given.

Usage: check_run_file.py RUN.h5 EXPECTED.json OUTPUT-FORMAT.md
       check_run_file.py RUN.h5 - OUTPUT-FORMAT.md     (layout only, sizes taken from the file)

- The layout: every table row of the document whose first cell is a path (`/...`) is one dataset or
  attribute (`object@attribute`); NNNNNN stands for every snapshot and <stage> for every stage name.
  The file must hold exactly these, with the documented type and shape (rows whose meaning starts
  with "Only" may be missing). Every dataset with a units cell has a `units` attribute equal to it
  (implied, not listed as a row); the numeric datasets of snapshots are compressed (gzip, shuffle)
  and checksummed.
- The values: EXPECTED.json (written by test_run_file.cpp from its own model and states, not from the
  file) lists the sizes and the values of every dataset; they must match.
Exits 0 when everything matches, 1 with one line per problem otherwise.
"""
import json
import re
import sys

import h5py
import numpy as np

problems = []


def fail(message):
    problems.append(message)


def parse_layout(doc_path):
    """(path, type, shape, units, optional) of every documented dataset and attribute."""
    rows = []
    pattern = re.compile(r"^\| `(/[^`]*)` \| ([\w]+) \| ([^|]+) \| ([^|]*) \| (.*)\|\s*$")
    with open(doc_path, encoding="utf-8") as doc:
        for line in doc:
            match = pattern.match(line)
            if match:
                rows.append((match.group(1), match.group(2), match.group(3).strip(), match.group(4).strip(),
                             match.group(5).strip().startswith("Only")))
    return rows


def actual_items(h5):
    """Every dataset path and every attribute (as object@name) in the file, and the group paths."""
    items, groups = set(), set()
    for name in h5.attrs:
        items.add("/@" + name)

    def visit(name, obj):
        path = "/" + name
        if isinstance(obj, h5py.Dataset):
            items.add(path)
        else:
            groups.add(path)
        for attribute in obj.attrs:
            items.add(path + "@" + attribute)

    h5.visititems(visit)
    return items, groups


def as_float_array(values):
    def convert(x):
        if isinstance(x, list):
            return [convert(y) for y in x]
        return float(x)  # accepts "inf" and "-inf" (JSON has no infinity)

    return np.array(convert(values), dtype=float)


def check_dtype(path, obj, type_name):
    dtype = obj.dtype
    if type_name == "string":
        if h5py.check_string_dtype(dtype) is None:
            fail(f"{path}: expected a string, found {dtype}")
        return
    expected = {"float64": "<f8", "int64": "<i8", "int32": "<i4", "int8": "|i1"}[type_name]
    if dtype.str != expected:
        fail(f"{path}: expected {type_name}, found {dtype}")


def evaluate_shape(text, sizes):
    if text == "scalar":
        return ()
    value = eval(text, {"__builtins__": {}}, dict(sizes))  # e.g. "(N, 3)" or "(P+1)"
    return tuple(value) if isinstance(value, tuple) else (value,)


def get(h5, path):
    """The object (dataset, group or file) and the attribute name (or None) of a documented path."""
    if "@" in path:
        object_path, attribute = path.split("@")
        return h5[object_path or "/"], attribute
    return h5[path], None


def sizes_from_file(run_path):
    """What the layout check needs, read from the file itself (no value is checked then)."""
    with h5py.File(run_path, "r") as h5:
        p = h5["/model/polyhedra"]
        sizes = {
            "N": int(h5["/model"].attrs["body_count"]),
            "P": len(p["vertex_offset"]) - 1,
            "V": p["vertices"].shape[0],
            "F": len(p["face_offset"]) - 1,
            "K": len(p["face_vertices"]),
            "W": h5["/model/planes/normal"].shape[0],
            "B": h5["/model/boxes/half_extents"].shape[0],
            "M": len(h5["/model/materials/name"]),
            "S": len(h5["/series/step"]),
        }
        stages = [str(s) for s in h5["/series/stage_seconds"].attrs["stage_order"]]
        snapshots = [{"contact_gap": [0.0] * len(h5[f"/snapshots/{name}/contact_gap"])}
                     for name in sorted(h5["/snapshots"].keys())]
    return {"sizes": sizes, "stage_names": stages, "snapshots": snapshots, "layout_only": True}


def main():
    run_path, expected_path, doc_path = sys.argv[1:4]
    if expected_path == "-":
        expected = sizes_from_file(run_path)
    else:
        with open(expected_path, encoding="utf-8") as f:
            expected = json.load(f)
    layout = parse_layout(doc_path)
    if len(layout) < 40:
        fail(f"{doc_path}: only {len(layout)} layout rows found; was the table format changed?")

    with h5py.File(run_path, "r") as h5:
        stages = [str(s) for s in h5["/series/stage_seconds"].attrs["stage_order"]]
        snapshots = sorted(h5["/snapshots"].keys())
        if stages != expected["stage_names"]:
            fail(f"stage_order {stages} != {expected['stage_names']}")
        if snapshots != [f"{k:06d}" for k in range(len(expected["snapshots"]))]:
            fail(f"snapshot names {snapshots}")

        # Expand the documented layout over snapshots and stages.
        documented = []
        units_of = {}
        optional = set()
        for path, type_name, shape, units, is_optional in layout:
            names = snapshots if "NNNNNN" in path else [None]
            for snapshot_index, snapshot in enumerate(names):
                for stage in stages if "<stage>" in path else [None]:
                    concrete = path
                    sizes = dict(expected["sizes"])
                    sizes["T"] = len(expected["snapshots"])
                    sizes["stages"] = len(stages)
                    if snapshot is not None:
                        concrete = concrete.replace("NNNNNN", snapshot)
                        sizes["C"] = len(expected["snapshots"][snapshot_index]["contact_gap"])
                    if stage is not None:
                        concrete = concrete.replace("<stage>", stage)
                    documented.append((concrete, type_name, evaluate_shape(shape, sizes)))
                    if is_optional:
                        optional.add(concrete)
                    if "@" not in concrete and units:
                        units_of[concrete] = units

        items, _ = actual_items(h5)
        documented_paths = {p for p, _, _ in documented} | {p + "@units" for p in units_of}
        for extra in sorted(items - documented_paths):
            fail(f"{extra}: in the file but not in {doc_path}")
        for missing in sorted(documented_paths - items):
            if missing not in optional and missing.split("@")[0] not in optional:
                fail(f"{missing}: documented but not in the file")

        # Units: the attribute of every dataset equals the table's units column.
        for path, units in units_of.items():
            if path in items and (path + "@units") in items and h5[path].attrs["units"] != units:
                fail(f"{path}@units = {h5[path].attrs['units']!r}, documented {units!r}")

        # Storage: numeric datasets of the snapshots and model are shuffled, deflated and
        # checksummed; the growing series columns checksummed only (compressed chunks that grow
        # move in the file and do not survive a killed run); empty and scalar ones stay contiguous.
        for path in units_of:
            if path not in items or not path.startswith(("/snapshots/", "/series/", "/model/")):
                continue
            dataset = h5[path]
            if dataset.shape and dataset.size > 0 or dataset.maxshape != dataset.shape:
                storage = (None, None, False, True) if path.startswith("/series/") else ("gzip", 4, True, True)
                if (dataset.compression, dataset.compression_opts, dataset.shuffle, dataset.fletcher32) != storage:
                    fail(f"{path}: stored with {dataset.compression} {dataset.compression_opts}, shuffle {dataset.shuffle}, "
                         f"fletcher32 {dataset.fletcher32}; expected {storage}")

        # Types and shapes.
        for path, type_name, shape in documented:
            if path not in items:
                continue
            obj, attribute = get(h5, path)
            if attribute is not None:
                value = obj.attrs[attribute]
                if type_name == "string":
                    ok = isinstance(value, str) or (isinstance(value, np.ndarray) and value.dtype == object)
                    if not ok:
                        fail(f"{path}: expected a string attribute, found {type(value)}")
                    actual_shape = np.shape(value) if isinstance(value, np.ndarray) else ()
                else:
                    check_dtype(path, obj.attrs.get_id(attribute), type_name)
                    actual_shape = np.shape(value)
            else:
                check_dtype(path, obj, type_name)
                actual_shape = obj.shape
                _ = obj[()]  # every dataset, empty ones included, must be readable
            if tuple(actual_shape) != shape:
                fail(f"{path}: shape {tuple(actual_shape)}, documented {shape}")

        # Values.
        if expected.get("layout_only"):
            for problem in problems:
                print("check_run_file:", problem)
            print(f"check_run_file: layout only, {len(layout)} documented rows, {len(problems)} problems")
            return 1 if problems else 0
        if h5.attrs["format"] != "rubble-run" or int(h5.attrs["format_version"]) != 2:
            fail("root format attributes")
        if not re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", h5.attrs["created"]):
            fail(f"created = {h5.attrs['created']!r} is not ISO 8601 UTC")
        if h5["/run"].attrs["status"] != expected.get("status", "running"):
            fail(f"/run@status = {h5['/run'].attrs['status']!r}, expected {expected.get('status', 'running')!r}")
        for name, (value, units, source) in expected.get("run", {}).items():
            dataset = h5.get(f"/run/{name}")
            if dataset is None:
                fail(f"/run/{name}: missing")
            elif (dataset[()], dataset.attrs["units"], dataset.attrs["source"]) != (value, units, source):
                fail(f"/run/{name}: {dataset[()]} {dataset.attrs['units']} ({dataset.attrs['source']}), "
                     f"expected {value} {units} ({source})")
        if h5["/scene"].asstr()[()] != expected["scene"]:
            fail("/scene differs from the scene text given")
        for key in ("body_count", "grain_count"):
            if int(h5["/model"].attrs[key]) != expected["model_attributes"][key]:
                fail(f"/model@{key}")
        for path, values in expected["datasets"].items():
            if path not in h5:
                continue
            if isinstance(values, list) and values and isinstance(values[0], str) and path.endswith("name"):
                actual = [s for s in h5[path].asstr()[()]]
                if actual != values:
                    fail(f"{path}: {actual} != {values}")
                continue
            want = as_float_array(values)
            got = np.asarray(h5[path][()], dtype=float)
            if got.shape != want.shape and not (got.size == 0 and want.size == 0):
                fail(f"{path}: shape {got.shape} != expected {want.shape}")
            elif not np.array_equal(got.reshape(want.shape) if got.size else want, want):
                fail(f"{path}: values differ: {got.ravel()[:8]} vs {want.ravel()[:8]}")
        for index, snapshot in enumerate(expected["snapshots"]):
            group = h5[f"/snapshots/{index:06d}"]
            if group.attrs["time"] != snapshot["time"] or group.attrs["step"] != snapshot["step"]:
                fail(f"{group.name}: time/step attributes")
            if h5["/snapshot_time"][index] != snapshot["time"] or h5["/snapshot_step"][index] != snapshot["step"]:
                fail(f"/snapshot_time or /snapshot_step row {index} differs from {group.name}")
            if group.attrs["interrupted"] != snapshot.get("interrupted", 0):
                fail(f"{group.name}@interrupted = {group.attrs['interrupted']}")
            for key, values in snapshot.items():
                if key in ("time", "step", "interrupted"):
                    continue
                want = as_float_array(values)
                got = np.asarray(group[key][()], dtype=float)
                if want.size == 0:
                    if got.size != 0:
                        fail(f"{group.name}/{key}: expected empty")
                elif got.shape != want.shape or not np.array_equal(got, want):
                    fail(f"{group.name}/{key}: values differ")

    for problem in problems:
        print("check_run_file:", problem)
    print(f"check_run_file: {len(layout)} documented rows, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())

"""Parquet tables as the Hugging Face ``datasets`` library writes them, so the ecosystem's reader (which
loads them with their declared features) and the Hub's viewer read them as their own.

A feature of shape (n,) is a list of n values, (1,) a plain value, (h, w) a list of lists; the
schema carries the ``datasets`` feature description under the ``huggingface`` key.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

ARROW_TYPE = {
    "string": "string",
    "float64": "float64",
    "float32": "float32",
    "int64": "int64",
    "int32": "int32",
    "bool": "bool_",
}


def hf_feature(feature: dict) -> dict:
    """The ``datasets`` description of a feature of info.json (or of a metadata table's column)."""
    dtype, shape = feature["dtype"], list(feature["shape"])
    if dtype == "string_list":
        return {"feature": {"dtype": "string", "_type": "Value"}, "_type": "List"}
    if len(shape) == 1 and shape[0] == 1:
        return {"dtype": dtype, "_type": "Value"}
    if len(shape) == 1:
        return {"feature": {"dtype": dtype, "_type": "Value"}, "length": shape[0], "_type": "List"}
    return {"shape": shape, "dtype": dtype, "_type": f"Array{len(shape)}D"}


def _arrow_type(pa, feature: dict):
    if feature["dtype"] == "string_list":
        return pa.list_(pa.string())
    base = getattr(pa, ARROW_TYPE[feature["dtype"]])()
    shape = list(feature["shape"])
    if shape == [1]:
        return base
    if len(shape) == 1:
        return pa.list_(base, shape[0])
    return pa.list_(pa.list_(base, shape[1]))  # what datasets stores an Array2D as, in a file


def write_table(path: Path, columns: dict, features: dict[str, dict], pandas_index: str = "") -> None:
    """``columns`` (each (n, *shape)) into ``path`` with the features' types and description;
    ``pandas_index``: the column pandas reads back as the table's index (meta/tasks.parquet)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    arrays, fields = [], []
    for name, values in columns.items():
        feature = features[name]
        kind = _arrow_type(pa, feature)
        if feature["dtype"] in ("string", "string_list"):
            arrays.append(pa.array(list(values), type=kind))
        elif list(feature["shape"]) == [1]:
            arrays.append(pa.array(np.asarray(values).reshape(-1), type=kind))
        else:
            arrays.append(pa.array(np.asarray(values).tolist(), type=kind))
        fields.append(pa.field(name, kind))
    described = {"info": {"features": {name: hf_feature(features[name]) for name in columns}}}
    metadata = {"huggingface": json.dumps(described)}
    if pandas_index:
        metadata["pandas"] = json.dumps(_pandas_metadata(list(columns), features, pandas_index))
    schema = pa.schema(fields, metadata=metadata)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.Table.from_arrays(arrays, schema=schema), path, compression="snappy")


def _pandas_metadata(names: list[str], features: dict[str, dict], index: str) -> dict:
    def column(name: str) -> dict:
        text = features[name]["dtype"] == "string"
        kind = "unicode" if text else features[name]["dtype"]
        return {
            "name": name,
            "field_name": name,
            "pandas_type": kind,
            "numpy_type": "object" if text else kind,
            "metadata": None,
        }

    return {
        "index_columns": [index],
        "column_indexes": [
            {
                "name": None,
                "field_name": None,
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": {"encoding": "UTF-8"},
            }
        ],
        "columns": [column(n) for n in names if n != index] + [column(index)],
        "creator": {"library": "pyarrow", "version": "tactile-rig"},
        "pandas_version": "2.2.0",
    }


def read_table(path: Path) -> dict[str, np.ndarray]:
    """A data parquet's columns as arrays (n, *shape)."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    out = {}
    for name in table.column_names:
        column = table.column(name).to_pylist()
        out[name] = np.asarray(column)
    return out

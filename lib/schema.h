/* schema.h — the machine-readable side of schemas/ (one .md per type): which datasets and
 * attributes each crom file type has, with dtype, shape, units and meaning,
 * and a checker used by `crom-info --check`.
 *
 * Shapes are comma-separated dimension symbols: a number is a fixed extent, a
 * name (nv, nt, F, r, ...) must take the same value everywhere in one file,
 * '?' is any extent. Paths may contain one '*' standing for every member of a
 * group (regions/NAME). Frame fields live under frames/ with a leading F.
 */
#ifndef CROM_SCHEMA_H
#define CROM_SCHEMA_H

#include <stdio.h>

#include "io.h"

typedef struct {
    const char *path;    /* dataset path relative to the root */
    const char *type;    /* "f64", "f32", "i32" */
    const char *shape;   /* "nv,3" */
    int required;        /* 1 required, 0 optional */
    const char *units;   /* SI units, "1" for counts/indices */
    const char *meaning;
} crom_schema_dset;

typedef struct {
    const char *name;
    const char *type;    /* "str", "i64", "f64", "f64[3]" ... */
    int required;
    const char *meaning;
} crom_schema_attr;

typedef struct {
    const char *schema;  /* "crom/mesh" */
    int version;         /* the version this crom writes and understands */
    const char *summary;
    const crom_schema_attr *attrs;  /* root attributes beyond the common ones */
    const crom_schema_dset *dsets;
    int series;          /* has /frames (a time series) */
} crom_schema;

/* The spec of a schema name, or NULL. */
const crom_schema *crom_schema_find(const char *name);

/* All specs: an array ending with an entry whose `schema` is NULL. */
const crom_schema *crom_schema_all(void);

/* Check an open input against its schema: datasets, dtypes, shapes, required
 * attributes, then the schema's own semantic checks (e.g. a mesh's tets are
 * positively oriented, frames are finite, the run is complete). Each
 * violation is printed to `report` as one line; returns their number (0 =
 * valid), or -1 on an internal failure. Reads every frame of a series. */
int crom_schema_check(crom_in *in, FILE *report);

#endif

/* schema.h — the one table of crom's file types: for each type (one .md per
 * type in schemas/), which datasets and attributes it has, with dtype,
 * shape, units and description. The writers take every dataset's units and
 * description from it (crom_h5_put_* and crom_out_field in io.c), io.c
 * refuses to write a dataset or attribute it does not list, `crom-info
 * --check` validates files against it (validate.c), and
 * tests/prog/schemas.sh checks that the documents in schemas/ say the same. Plain data
 * with lookups: no HDF5, no state.
 *
 * Shapes are comma-separated dimension symbols: a number is a fixed extent, a
 * name (nv, nt, F, r, ...) must take the same value everywhere in one file,
 * '?' is any extent. Paths are relative to the root and may contain '*'
 * standing for any one member of a group (regions/NAME). Frame fields live
 * under frames/ with a leading F.
 */
#ifndef CROM_SCHEMA_H
#define CROM_SCHEMA_H

typedef struct {
    const char *path;    /* dataset path relative to the root */
    const char *type;    /* "f64", "f32", "i32" */
    const char *shape;   /* "nv,3" */
    int required;        /* 1 required, 0 optional */
    const char *units;   /* SI units, "1" for dimensionless numbers, counts and indices */
    const char *meaning; /* written as the dataset's `description` attribute */
    const char *kinds;   /* NULL, or the model kinds (`basis` names, space-separated)
                          * for which this second row of the same path holds: they
                          * differ in units (a data-free latent is dimensionless) */
} crom_schema_dset;

typedef struct {
    const char *name;
    const char *type;    /* "str", "i64", "f64", "f64[3]" */
    int required;        /* root: in every file; on an object: whenever it exists */
    const char *meaning;
    const char *object;  /* NULL for a root attribute, else the path of the group
                          * or dataset it is on ('*' for any member of a group) */
} crom_schema_attr;

typedef struct {
    const char *schema;  /* "crom/mesh" */
    int version;         /* the version this crom writes and understands */
    const char *summary;
    const crom_schema_attr *attrs;  /* root attributes beyond the common ones */
    const crom_schema_attr *objattrs; /* attributes of groups and datasets
                                       * (beside every dataset's units and description) */
    const crom_schema_dset *dsets;
    int series;          /* has /frames (a time series) */
} crom_schema;

/* The spec of a schema name, or NULL. */
const crom_schema *crom_schema_find(const char *name);

/* All specs: an array ending with an entry whose `schema` is NULL. */
const crom_schema *crom_schema_all(void);

/* The root attributes of every crom file (schema, schema_version, history,
 * crom_version), ending with a NULL name. */
const crom_schema_attr *crom_schema_common_attrs(void);

/* 1 if `path` (no leading '/') matches the table path `pattern`, where a '*'
 * stands for one path component; else 0. */
int crom_schema_path_match(const char *pattern, const char *path);

/* The row of dataset `path` in s (a member of a '*' group matches its row)
 * for model kind `kind`: the row whose `kinds` lists it, else the row with no
 * `kinds`. NULL when s does not list the path. */
const crom_schema_dset *crom_schema_dset_find(const crom_schema *s, const char *path,
                                              const char *kind);

/* Attribute `name` of the root (object NULL, common attributes included) or
 * of the object at `object`, or NULL when s does not list it. */
const crom_schema_attr *crom_schema_attr_find(const crom_schema *s, const char *object,
                                              const char *name);

#endif

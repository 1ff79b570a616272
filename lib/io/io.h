/* io.h — crom files: HDF5 at rest, HDF5 file images or framed streams in pipes.
 *
 * Every crom file is HDF5 with root attributes `schema` ("crom/mesh"),
 * `schema_version` (int) and `history` (one line per stage that made it).
 * Time series (trajectories, latent trajectories) keep their per-frame data in
 * /frames/<field> datasets with a leading frame dimension; through a pipe they
 * may instead travel as a framed stream (schemas/stream.md): an HDF5 image of
 * everything but the frames, then one record per frame, then an end record.
 * Readers accept both forms, from a path or from stdin ("-" or NULL).
 *
 * Outputs: a named output is written to a temporary file beside it and renamed
 * on success (a target that is a device or FIFO, such as /dev/null, is
 * written in place instead); stdout gets an HDF5 image (when stdout is a regular file, or for
 * non-series files) or a stream (series into a pipe). Binary output to a
 * terminal is refused.
 */
#ifndef CROM_IO_H
#define CROM_IO_H

#include <stddef.h>
#include <stdio.h>

#include <hdf5.h>

#include "base/clock.h"

#define CROM_IO_MAX_FIELDS 24
#define CROM_IO_MAX_RANK 4

typedef struct {
    char name[48];
    int rank;                      /* per-frame rank (0 = scalar) */
    hsize_t dims[CROM_IO_MAX_RANK];   /* per-frame shape */
    size_t count;                  /* per-frame element count */
    size_t offset;                 /* offset in the packed frame (doubles) */
    hid_t dset;                    /* open /frames/<name> (HDF5 form) */
} crom_io_field;

enum { CROM_IO_H5 = 1, CROM_IO_STREAM = 2 };

/* ------------------------------------------------------------------ inputs */

typedef struct {
    hid_t h5;             /* the HDF5 content (for a stream: its header) */
    char name[512];       /* path, or "stdin" */
    int form;             /* CROM_IO_H5 or CROM_IO_STREAM */
    char schema[64];
    int version;
    char *history;        /* root `history` (owned) */
    /* time series */
    int nfields;
    crom_io_field fields[CROM_IO_MAX_FIELDS];
    size_t frame_len;     /* doubles per packed frame */
    double *frame;        /* the current frame, packed in field order */
    size_t frame_cap;     /* bytes allocated at frame */
    long nframes;         /* HDF5: number stored; stream: read so far */
    long cursor;          /* index of the next frame crom_in_next() returns */
    int complete;         /* 1 complete, 0 marked incomplete, -1 unknown yet */
    /* private */
    FILE *fp;
    int own_fp;
    void *image;
    size_t image_size;
} crom_in;

/* Open any crom input: path, or stdin when path is NULL or "-". Detects HDF5
 * vs stream; reads schema, version, history, and the frame fields of a time
 * series. Returns 0, or CROM_ENOINPUT (missing/unreadable), CROM_EDATA (not a
 * crom file, truncated, corrupt), CROM_EUSAGE (stdin is a terminal). */
int crom_in_open(crom_in *in, const char *path);

/* Check the schema: returns 0 if in is `schema` with version <= max_version,
 * else CROM_EDATA with "NAME is crom/x v1, expected crom/y" or a newer-version
 * message. */
int crom_in_expect(const crom_in *in, const char *schema, int max_version);

/* Index of frame field `name`, or -1 (with an error recorded) if absent. */
int crom_in_field(const crom_in *in, const char *name);

/* Pointer to field i of the current frame (valid until the next call). */
const double *crom_in_get(const crom_in *in, int field);

/* Read the next frame into in->frame. Returns 1 when a frame was read, 0 at
 * the end, or an error code (negative of it: -CROM_EDATA for a truncated
 * stream). */
int crom_in_next(crom_in *in);

/* Random access for HDF5 inputs: make frame k current. Error for streams
 * unless k == cursor. */
int crom_in_seek(crom_in *in, long k);

/* Read every remaining frame of a stream so nframes/complete are known, while
 * keeping all frames in memory: returns a [nframes][frame_len] array (owned by
 * caller) with *nframes set. Works for both forms. */
int crom_in_read_all(crom_in *in, double **frames, long *nframes);

void crom_in_close(crom_in *in);

/* ----------------------------------------------------------------- outputs */

typedef struct {
    hid_t h5;             /* write static content here (root group) */
    char name[512];       /* path or "stdout" */
    int form;             /* CROM_IO_H5 or CROM_IO_STREAM */
    int series;           /* has frame fields */
    int to_stdout;
    int begun;
    int nfields;
    crom_io_field fields[CROM_IO_MAX_FIELDS];
    size_t frame_len;
    double *pack;
    long nframes;
    /* private */
    char *target, *tmp;
    FILE *fp;             /* stream output */
    FILE *out;            /* a named device or FIFO written in place */
    int done;
} crom_out;

enum {
    CROM_OUT_PLAIN = 0,   /* one HDF5 file, no frames */
    CROM_OUT_SERIES = 1,  /* time series: stream into a pipe, HDF5 otherwise */
    CROM_OUT_SERIES_H5 = 2,     /* time series, always HDF5 */
    CROM_OUT_SERIES_STREAM = 3  /* time series, always a stream */
};

/* Create an output: path, or stdout when path is NULL or "-". Writes the root
 * attributes schema, schema_version and history (parent_history, may be NULL,
 * plus a line for this stage from cli). Returns 0, CROM_EUSAGE (stdout is a
 * terminal), or CROM_ECANTCREAT. */
int crom_out_create(crom_out *o, const char *path, const char *schema,
                    int version, const char *cmdline,
                    const char *parent_history, int kind);

/* Declare a per-frame field /frames/<name> (series only, before
 * crom_out_begin). dims may be NULL for rank 0. Its `units` and `description`
 * attributes are those of the row of the output's schema table (schema.h) for
 * model kind `kind` (a `basis` name, or NULL); a field the table does not
 * list, or lists with another rank, is CROM_EINTERNAL. */
int crom_out_field(crom_out *o, const char *name, int rank, const hsize_t *dims,
                   const char *kind);

/* End of static content: for a stream this writes the header. */
int crom_out_begin(crom_out *o);

/* Append one frame: vals[i] points to field i's data. */
int crom_out_frame(crom_out *o, const double *const *vals);

/* Finish successfully: mark complete, write the image or rename into place. */
int crom_out_commit(crom_out *o);

/* Finish after a failure. A series that has frames is kept, marked incomplete
 * (readable, never looking complete); anything else is removed. Returns 0 if
 * something was kept. Safe to call after commit (does nothing). */
int crom_out_fail(crom_out *o);

/* ------------------------------------------------ plain (non-HDF5) outputs
 * For VTU, PVD, OBJ, PLY, PNG, CSV ...: written to a temporary file beside the
 * target and renamed on commit; "-" or NULL is stdout. */
typedef struct {
    FILE *f;
    char *target, *tmp;
    int to_stdout;
    int in_place;        /* target is a device or FIFO: written directly */
} crom_fileout;

/* Open for writing; binary = 1 refuses a terminal on stdout. */
int crom_fileout_open(crom_fileout *o, const char *path, int binary);
/* Close and rename into place; returns 0 or CROM_EIO/CROM_ECANTCREAT. */
int crom_fileout_commit(crom_fileout *o);
/* Close and remove the temporary file. */
void crom_fileout_abort(crom_fileout *o);

/* End a run that streamed frames to o, with an optional per-step table in
 * stats (NULL or not open: none), given the run's code rc. rc == 0: commit
 * the table, then o (a table that cannot be written fails the run).
 * Otherwise, or if that fails: remove the table and finish o with
 * crom_out_fail, adding "... keeps the N frames done, marked incomplete" to
 * the message when frames were kept. Returns the run's final code. */
int crom_out_finish_run(crom_out *o, crom_fileout *stats, int rc);

/* ---------------------------------------------------------- HDF5 helpers
 * Each returns 0 or an error code with a message naming the object.
 *
 * Datasets of a crom file (loc is its root or a group in it, and its root
 * attribute `schema` names a type of schema.h): crom_h5_put_* write dataset
 * `name` (a path relative to loc) with the dtype and rank the table gives
 * for it, and its `units` and `description` attributes from the table; a
 * dataset the table does not list, or lists with another dtype or rank, is
 * CROM_EINTERNAL. Attributes set with crom_h5_set_* on a crom file must be
 * in its table too (with that type), besides the units and description of
 * a dataset. */
int crom_h5_put_f64(hid_t loc, const char *name, int rank, const hsize_t *dims,
                    const double *data);
int crom_h5_put_f32(hid_t loc, const char *name, int rank, const hsize_t *dims,
                    const float *data);
int crom_h5_put_i32(hid_t loc, const char *name, int rank, const hsize_t *dims,
                    const int *data);

/* Datasets of any other HDF5 file (XDMF heavy data): `units` and
 * `description` attributes when those are non-NULL. Refuses a crom file
 * (CROM_EINTERNAL: its datasets are written with crom_h5_put_*). */
int crom_h5_write(hid_t loc, const char *name, hid_t memtype, int rank,
                  const hsize_t *dims, const void *data, const char *units,
                  const char *description);
int crom_h5_write_f64(hid_t loc, const char *name, int rank, const hsize_t *dims,
                      const double *data, const char *units, const char *desc);
int crom_h5_write_f32(hid_t loc, const char *name, int rank, const hsize_t *dims,
                      const float *data, const char *units, const char *desc);
int crom_h5_write_i32(hid_t loc, const char *name, int rank, const hsize_t *dims,
                      const int *data, const char *units, const char *desc);

/* Read a whole dataset of the given rank (dims filled in, data allocated with
 * malloc). rank < 0 accepts any rank up to CROM_IO_MAX_RANK and stores it in
 * *rank_out. */
int crom_h5_read(hid_t loc, const char *name, hid_t memtype, int rank,
                 hsize_t *dims, void **data);
int crom_h5_read_f64(hid_t loc, const char *name, int rank, hsize_t *dims,
                     double **data);
int crom_h5_read_f32(hid_t loc, const char *name, int rank, hsize_t *dims,
                     float **data);
int crom_h5_read_i32(hid_t loc, const char *name, int rank, hsize_t *dims,
                     int **data);
/* Rank and dims of a dataset without reading it. */
int crom_h5_shape(hid_t loc, const char *name, int *rank, hsize_t *dims);

/* 1 if the link exists (path may have several components), else 0. */
int crom_h5_has(hid_t loc, const char *path);

/* Names of the members of group `path` under loc, sorted by name: a
 * NULL-terminated malloc'ed list (free with crom_h5_list_free). NULL with
 * an error recorded when the group cannot be opened or listed. */
char **crom_h5_list(hid_t loc, const char *path);
void crom_h5_list_free(char **list);

/* Create a group (or open an existing one); returns the id or a negative
 * value with an error recorded. */
hid_t crom_h5_group(hid_t loc, const char *name);

/* Attributes on object `obj` (a path relative to loc, "." for loc itself). */
int crom_h5_set_str(hid_t loc, const char *obj, const char *name, const char *value);
int crom_h5_get_str(hid_t loc, const char *obj, const char *name, char **value);
int crom_h5_set_f64(hid_t loc, const char *obj, const char *name, const double *v, int n);
int crom_h5_get_f64(hid_t loc, const char *obj, const char *name, double *v, int n);
int crom_h5_set_i64(hid_t loc, const char *obj, const char *name, long long v);
int crom_h5_get_i64(hid_t loc, const char *obj, const char *name, long long *v);
int crom_h5_has_attr(hid_t loc, const char *obj, const char *name);

/* Silence HDF5's own error printing (idempotent). */
void crom_h5_quiet(void);

#endif

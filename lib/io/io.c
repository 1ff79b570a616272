/* io.c — crom files on disk and through pipes (see io.h, schemas/stream.md). */
#include <errno.h>
#include <libgen.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <hdf5_hl.h>

#include "base/array.h"
#include "base/clock.h"
#include "base/err.h"
#include "io/h5probe.h"
#include "io/io.h"
#include "io/schema.h"

#define STREAM_MAGIC "CROMSTRM"
#define STREAM_VERSION 1u
static const unsigned char hdf5_sig[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the crom stream format is little-endian; add byte swapping for this host"
#endif

/* ------------------------------------------------- temporary-file cleanup
 * Named outputs live under a temporary name until commit. If the program is
 * interrupted (SIGINT/SIGTERM/SIGHUP) the temporary files are removed so a
 * half-written file never stays behind. This small registry is the only
 * process-wide mutable state in io.c, and a global it must be: a signal
 * handler is called with nothing but the signal number, so the names it
 * removes can only be found in a global. */
#define MAX_TMP 16
static char *volatile tmp_registry[MAX_TMP];
static char *tmp_targets[MAX_TMP]; /* the name each temporary file will get */

static void cleanup_signal(int sig)
{
    for (int i = 0; i < MAX_TMP; i++)
        if (tmp_registry[i])
            unlink(tmp_registry[i]);
    signal(sig, SIG_DFL);
    raise(sig);
}

static void tmp_register(char *path, const char *target)
{
    /* (again at every registration: installing the same handler twice is harmless) */
    signal(SIGINT, cleanup_signal);
    signal(SIGTERM, cleanup_signal);
    signal(SIGHUP, cleanup_signal);
    for (int i = 0; i < MAX_TMP; i++)
        if (!tmp_registry[i]) {
            tmp_targets[i] = strdup(target);
            tmp_registry[i] = path;
            return;
        }
}

static void tmp_unregister(const char *path)
{
    for (int i = 0; i < MAX_TMP; i++)
        if (path && tmp_registry[i] == path) {
            tmp_registry[i] = NULL;
            free(tmp_targets[i]);
            tmp_targets[i] = NULL;
        }
}

/* The name a file HDF5 writes under `path` is reported by: the target of a
 * temporary file, else path itself. */
static const char *target_name(const char *path)
{
    for (int i = 0; i < MAX_TMP; i++)
        if (tmp_registry[i] && tmp_targets[i] && !strcmp(tmp_registry[i], path))
            return tmp_targets[i];
    return path;
}

/* ------------------------------------------ system errors under HDF5
 * HDF5 tells a failed write(2) only as text on its error stack ("file write
 * failed: ..., filename = 'x', ..., errno = 28, error message = 'No space
 * left on device'"), and the call that fails is often a later one than the
 * write that lost the data (a chunk or metadata flush at H5Dclose or
 * H5Fclose). The handler crom_h5_quiet installs reads the errno out of every
 * failure's stack and keeps the last one with its file, so the failure is
 * reported as the system's error (exit 74) by whichever call sees it. Kept
 * per thread, like errno and crom_err's message. */
static _Thread_local int sys_errno;
static volatile int h5_broken; /* see h5_at_exit */
static _Thread_local char sys_file[512];

static herr_t note_sys_error(unsigned n, const H5E_error2_t *e, void *data)
{
    (void)n;
    int *found = data;
    const char *p = e->desc && !*found ? strstr(e->desc, "errno = ") : NULL;
    if (!p)
        return 0;
    int v = atoi(p + 8);
    if (v <= 0)
        return 0;
    *found = 1;
    h5_broken = 1;
    sys_errno = v;
    sys_file[0] = 0;
    const char *f = strstr(e->desc, "filename = '");
    const char *end = f ? strchr(f + 12, '\'') : NULL;
    if (end && (size_t)(end - f - 12) < sizeof sys_file) {
        memcpy(sys_file, f + 12, (size_t)(end - f - 12));
        sys_file[end - f - 12] = 0;
    }
    return 0;
}

static herr_t on_h5_error(hid_t stack, void *data)
{
    (void)data;
    int found = 0;
    H5Ewalk2(stack, H5E_WALK_UPWARD, note_sys_error, &found);
    return 0;
}

/* The errno of the last system call that failed under HDF5 on file `path`
 * (an error without a file name counts for every file), or 0. */
static int sys_error_of(const char *path)
{
    return sys_errno && (!sys_file[0] || !strcmp(sys_file, path)) ? sys_errno : 0;
}

/* The errno of a failed system call on the file that holds loc, or 0. */
static int h5_sys_error(hid_t loc, char *path, size_t n)
{
    if (!sys_errno || loc < 0)
        return 0;
    ssize_t len = H5Fget_name(loc, path, n);
    return len > 0 && (size_t)len < n ? sys_error_of(path) : 0;
}

/* Record an HDF5 failure on the file that holds loc: as the system's error
 * ("out.h5: No space left on device", CROM_EIO) when a system call failed
 * under it, else as code with the message fmt. */
static int h5_fail(hid_t loc, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int h5_fail(hid_t loc, int code, const char *fmt, ...)
{
    char path[512];
    int e = h5_sys_error(loc, path, sizeof path);
    if (e)
        return crom_err(CROM_EIO, "%s: %s", target_name(path), strerror(e));
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return crom_err(code, "%s", msg);
}

/* HDF5 closes whatever is still open at exit (H5_term_library, registered
 * with atexit). A file whose H5Fclose failed stays in HDF5's tables half
 * torn down, and closing it again there crashes (SIGSEGV in H5F__close_cb);
 * an H5Fcreate that failed on a full disk leaves blocks that make the
 * shutdown print "HDF5: infinite loop closing library". So crom takes that
 * exit hook over and skips the library's shutdown once a close failed or a
 * system call failed under HDF5 (what it holds is still reachable, not
 * leaked). */
static void h5_at_exit(void)
{
    if (!h5_broken)
        H5close();
}

__attribute__((constructor)) static void h5_take_exit_hook(void)
{
    if (H5dont_atexit() >= 0)
        atexit(h5_at_exit);
}

/* ------------------------------------------------------------ small things */

void crom_h5_quiet(void) { H5Eset_auto2(H5E_DEFAULT, on_h5_error, NULL); }

static int write_all(FILE *f, const void *p, size_t n, const char *name)
{
    if (n && fwrite(p, 1, n, f) != n)
        return crom_err(CROM_EIO, "%s: %s", name, strerror(errno));
    return 0;
}

/* errno if it names an error of write(2) that a caller should see. */
static int write_errno(int e)
{
    return e == ENOSPC || e == EIO || e == EDQUOT || e == EFBIG ? e : 0;
}

int crom_fileout_error(FILE *f)
{
    if (!ferror(f))
        return 0;
    int e = write_errno(errno);
    return e ? crom_err(CROM_EIO, "%s", strerror(e)) : crom_err(CROM_EIO, "write failed");
}

/* Flush f and close it (unless it is to stay open, as stdout does). A
 * failure is recorded as "NAME: <the system's error>" (CROM_EIO). A write
 * that failed earlier left its mark on f but not always an error now (on
 * tmpfs the rest may fit in the last page): errno is still that write's
 * then, if it names a write error, else the message is "NAME: write failed". */
static int flush_close(FILE *f, int close_it, const char *name)
{
    int bad = ferror(f), before = errno;
    errno = 0;
    int e = fflush(f) ? errno : 0;
    if (close_it && fclose(f) && !e)
        e = errno;
    if (!e && bad)
        e = write_errno(before);
    if (e)
        return crom_err(CROM_EIO, "%s: %s", name, strerror(e));
    return bad ? crom_err(CROM_EIO, "%s: write failed", name) : 0;
}

/* Read exactly n bytes; returns n, or fewer at end of file. */
static size_t read_all(FILE *f, void *p, size_t n)
{
    size_t got = 0;
    while (got < n) {
        size_t k = fread((char *)p + got, 1, n - got, f);
        if (k == 0)
            break;
        got += k;
    }
    return got;
}

/* Read up to n bytes into *buf (capacity *cap, grown as the bytes arrive,
 * so a length read from a file costs no more memory than the file holds);
 * *got is how many arrived before end of file. */
static int read_grown(FILE *f, void **buf, size_t *cap, size_t n, size_t *got)
{
    *got = 0;
    if (!*buf) {
        int rc = crom_array_reserve(buf, cap, 1, 1);
        if (rc)
            return rc;
    }
    while (*got < n) {
        size_t want = n - *got < ((size_t)1 << 24) ? n - *got : (size_t)1 << 24;
        int rc = crom_array_reserve(buf, cap, *got + want, 1);
        if (rc)
            return rc;
        size_t k = read_all(f, (char *)*buf + *got, want);
        *got += k;
        if (k < want)
            break;
    }
    return 0;
}

/* ------------------------------------------------------------- attributes */

static hid_t open_obj(hid_t loc, const char *obj)
{
    if (!obj || !strcmp(obj, "."))
        return H5Oopen(loc, ".", H5P_DEFAULT);
    return H5Oopen(loc, obj, H5P_DEFAULT);
}

int crom_h5_has_attr(hid_t loc, const char *obj, const char *name)
{
    hid_t o = open_obj(loc, obj);
    if (o < 0)
        return 0;
    int r = H5Aexists(o, name) > 0;
    H5Oclose(o);
    return r;
}

/* ------------------------------------------ the table of the file's type */

/* The table of the crom file that holds loc: its root attribute `schema`
 * looked up in schema.h. NULL for another HDF5 file (XDMF heavy data), or
 * before `schema` is written. Quiet: records no error, so it may run while
 * a failure is being reported. */
static const crom_schema *file_schema(hid_t loc)
{
    const crom_schema *s = NULL;
    hid_t root = H5Oopen(loc, "/", H5P_DEFAULT);
    hid_t a = root >= 0 && H5Aexists(root, "schema") > 0 ? H5Aopen(root, "schema", H5P_DEFAULT) : -1;
    hid_t ft = a >= 0 ? H5Aget_type(a) : -1;
    if (ft >= 0 && H5Tget_class(ft) == H5T_STRING && H5Tis_variable_str(ft) > 0) {
        hid_t mt = H5Tcopy(H5T_C_S1);
        H5Tset_size(mt, H5T_VARIABLE);
        H5Tset_cset(mt, H5Tget_cset(ft));
        char *name = NULL;
        if (H5Aread(a, mt, &name) >= 0 && name) {
            s = crom_schema_find(name);
            H5free_memory(name);
        }
        H5Tclose(mt);
    }
    if (ft >= 0)
        H5Tclose(ft);
    if (a >= 0)
        H5Aclose(a);
    if (root >= 0)
        H5Oclose(root);
    return s;
}

/* The path of name under loc relative to the root, without a leading '/'
 * ("" for the root itself). */
static int object_path(hid_t loc, const char *name, char *path, size_t n)
{
    char base[512];
    hid_t o = H5Oopen(loc, ".", H5P_DEFAULT); /* a file id names its root group */
    ssize_t len = o < 0 ? -1 : H5Iget_name(o, base, sizeof base);
    if (o >= 0)
        H5Oclose(o);
    if (len < 1 || (size_t)len >= sizeof base)
        return crom_err(CROM_EINTERNAL, "cannot name the HDF5 object holding '%s'", name);
    const char *b = base + (base[0] == '/');
    int k = snprintf(path, n, "%s%s%s", b, *b && *name ? "/" : "", name);
    return k < 0 || (size_t)k >= n ? crom_err(CROM_EINTERNAL, "path of '%s' too long", name) : 0;
}

/* Attribute `name` of type `type` ("str", "i64", "f64", "f64[N]") on object o
 * of a crom file must be in its table: a root attribute, an attribute of
 * that object, or the units and description of a dataset. */
static int check_attr_documented(hid_t o, const char *name, const char *type)
{
    const crom_schema *s = file_schema(o);
    if (!s)
        return 0;
    char path[512];
    int rc = object_path(o, "", path, sizeof path);
    if (rc)
        return rc;
    if (*path && H5Iget_type(o) == H5I_DATASET && (!strcmp(name, "units") || !strcmp(name, "description")))
        return 0;
    const crom_schema_attr *a = crom_schema_attr_find(s, *path ? path : NULL, name);
    if (!a)
        return crom_err(CROM_EINTERNAL, "cannot write attribute '%s' of /%s: %s does not list it (lib/io/schema.c)",
                        name, path, s->schema);
    if (strcmp(a->type, type))
        return crom_err(CROM_EINTERNAL, "cannot write attribute '%s' of /%s as %s: %s lists it as %s", name, path,
                        type, s->schema, a->type);
    return 0;
}

static int set_attr(hid_t loc, const char *obj, const char *name, const char *schema_type, hid_t type,
                    hid_t space, const void *buf)
{
    hid_t o = open_obj(loc, obj);
    if (o < 0)
        return h5_fail(loc, CROM_EINTERNAL, "cannot open object '%s' for attribute '%s'",
                       obj ? obj : ".", name);
    int checked = check_attr_documented(o, name, schema_type);
    if (checked) {
        H5Oclose(o);
        return checked;
    }
    if (H5Aexists(o, name) > 0)
        H5Adelete(o, name);
    hid_t a = H5Acreate2(o, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
    int rc = 0;
    if (a < 0 || H5Awrite(a, type, buf) < 0)
        rc = h5_fail(o, CROM_EINTERNAL, "cannot write attribute '%s'", name);
    if (a >= 0)
        H5Aclose(a);
    H5Oclose(o);
    return rc;
}

int crom_h5_set_str(hid_t loc, const char *obj, const char *name, const char *value)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    H5Tset_size(t, H5T_VARIABLE);
    H5Tset_cset(t, H5T_CSET_UTF8);
    hid_t s = H5Screate(H5S_SCALAR);
    int rc = set_attr(loc, obj, name, "str", t, s, &value);
    H5Sclose(s);
    H5Tclose(t);
    return rc;
}

/* Open attribute `name` of object obj under loc; *o gets the object (close
 * both). Returns the attribute, or -1 with an error recorded. */
static hid_t open_attr(hid_t loc, const char *obj, const char *name, hid_t *o)
{
    *o = open_obj(loc, obj);
    if (*o < 0) {
        crom_err(CROM_EDATA, "no object '%s'", obj ? obj : ".");
        return -1;
    }
    if (H5Aexists(*o, name) <= 0) {
        H5Oclose(*o);
        crom_err(CROM_EDATA, "missing attribute '%s'", name);
        return -1;
    }
    return H5Aopen(*o, name, H5P_DEFAULT);
}

int crom_h5_get_str(hid_t loc, const char *obj, const char *name, char **value)
{
    *value = NULL;
    hid_t o, a = open_attr(loc, obj, name, &o);
    if (a < 0)
        return CROM_EDATA;
    hid_t ft = H5Aget_type(a);
    int rc = 0;
    if (H5Tget_class(ft) != H5T_STRING) {
        rc = crom_err(CROM_EDATA, "attribute '%s' is not a string", name);
    } else if (H5Tis_variable_str(ft) > 0) {
        hid_t mt = H5Tcopy(H5T_C_S1);
        H5Tset_size(mt, H5T_VARIABLE);
        H5Tset_cset(mt, H5Tget_cset(ft));
        char *s = NULL;
        if (H5Aread(a, mt, &s) < 0 || !s)
            rc = crom_err(CROM_EDATA, "cannot read attribute '%s'", name);
        else {
            *value = crom_strdup(s);
            H5free_memory(s);
        }
        H5Tclose(mt);
    } else {
        size_t n = H5Tget_size(ft);
        char *s = crom_calloc(n + 1, 1);
        hid_t mt = H5Tcopy(H5T_C_S1);
        H5Tset_size(mt, n + 1);
        if (!s || H5Aread(a, mt, s) < 0) {
            free(s);
            rc = crom_err(CROM_EDATA, "cannot read attribute '%s'", name);
        } else
            *value = s;
        H5Tclose(mt);
    }
    H5Tclose(ft);
    H5Aclose(a);
    H5Oclose(o);
    if (!rc && !*value)
        rc = crom_errcode() ? crom_errcode() : CROM_EINTERNAL;
    return rc;
}

int crom_h5_set_f64(hid_t loc, const char *obj, const char *name, const double *v, int n)
{
    hsize_t d = (hsize_t)n;
    hid_t s = n == 1 ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &d, NULL);
    char type[16] = "f64";
    if (n != 1)
        snprintf(type, sizeof type, "f64[%d]", n);
    int rc = set_attr(loc, obj, name, type, H5T_NATIVE_DOUBLE, s, v);
    H5Sclose(s);
    return rc;
}

int crom_h5_set_i64(hid_t loc, const char *obj, const char *name, long long v)
{
    hid_t s = H5Screate(H5S_SCALAR);
    int rc = set_attr(loc, obj, name, "i64", H5T_NATIVE_LLONG, s, &v);
    H5Sclose(s);
    return rc;
}

static int get_num_attr(hid_t loc, const char *obj, const char *name, hid_t mt,
                        void *v, int n)
{
    hid_t o, a = open_attr(loc, obj, name, &o);
    if (a < 0)
        return CROM_EDATA;
    hid_t s = H5Aget_space(a);
    hssize_t np = H5Sget_simple_extent_npoints(s);
    hid_t ft = H5Aget_type(a);
    int rc = 0;
    H5T_class_t cls = H5Tget_class(ft);
    if (cls != H5T_INTEGER && cls != H5T_FLOAT)
        rc = crom_err(CROM_EDATA, "attribute '%s' is not numeric", name);
    else if (np != n)
        rc = crom_err(CROM_EDATA, "attribute '%s' has %lld values, expected %d", name,
                      (long long)np, n);
    else if (H5Aread(a, mt, v) < 0)
        rc = crom_err(CROM_EDATA, "cannot read attribute '%s'", name);
    H5Tclose(ft);
    H5Sclose(s);
    H5Aclose(a);
    H5Oclose(o);
    return rc;
}

int crom_h5_get_f64(hid_t loc, const char *obj, const char *name, double *v, int n)
{
    return get_num_attr(loc, obj, name, H5T_NATIVE_DOUBLE, v, n);
}

int crom_h5_get_i64(hid_t loc, const char *obj, const char *name, long long *v)
{
    return get_num_attr(loc, obj, name, H5T_NATIVE_LLONG, v, 1);
}

/* --------------------------------------------------------------- datasets */

int crom_h5_has(hid_t loc, const char *path)
{
    /* check each component so missing intermediate groups are not errors */
    char buf[512];
    snprintf(buf, sizeof buf, "%s", path);
    for (char *p = buf + (buf[0] == '/'); ; p++) {
        if (*p == '/' || *p == 0) {
            char c = *p;
            *p = 0;
            if (H5Lexists(loc, buf, H5P_DEFAULT) <= 0)
                return 0;
            if (!c)
                return 1;
            *p = c;
        }
    }
}

static herr_t list_member(hid_t g, const char *name, const H5L_info_t *info, void *data)
{
    (void)g;
    (void)info;
    char ***list = data;
    size_t n = 0;
    while ((*list)[n])
        n++;
    char **nl = realloc(*list, sizeof(char *) * (n + 2));
    if (!nl)
        return -1;
    *list = nl;
    nl[n + 1] = NULL;
    return (nl[n] = strdup(name)) ? 0 : -1;
}

void crom_h5_list_free(char **list)
{
    for (size_t i = 0; list && list[i]; i++)
        free(list[i]);
    free(list);
}

char **crom_h5_list(hid_t loc, const char *path)
{
    char **list = calloc(1, sizeof(char *));
    hid_t g = list ? H5Gopen2(loc, path, H5P_DEFAULT) : -1;
    herr_t e = g < 0 ? -1 : H5Literate(g, H5_INDEX_NAME, H5_ITER_INC, NULL, list_member, &list);
    if (g >= 0)
        H5Gclose(g);
    if (e < 0) {
        crom_h5_list_free(list);
        crom_err(CROM_EDATA, "cannot list group '%s'", path);
        return NULL;
    }
    return list;
}

hid_t crom_h5_group(hid_t loc, const char *name)
{
    if (crom_h5_has(loc, name))
        return H5Gopen2(loc, name, H5P_DEFAULT);
    hid_t gcpl = H5Pcreate(H5P_GROUP_CREATE);
    H5Pset_obj_track_times(gcpl, 0);
    hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
    H5Pset_create_intermediate_group(lcpl, 1);
    hid_t g = H5Gcreate2(loc, name, lcpl, gcpl, H5P_DEFAULT);
    H5Pclose(gcpl);
    H5Pclose(lcpl);
    if (g < 0)
        h5_fail(loc, CROM_EINTERNAL, "cannot create group '%s'", name);
    return g;
}

static int write_dset(hid_t loc, const char *name, hid_t memtype, int rank, const hsize_t *dims,
                      const void *data, const char *units, const char *description)
{
    hid_t s = rank == 0 ? H5Screate(H5S_SCALAR) : H5Screate_simple(rank, dims, NULL);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_obj_track_times(dcpl, 0);
    hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
    H5Pset_create_intermediate_group(lcpl, 1);
    hid_t ft = memtype;
    if (H5Tequal(memtype, H5T_NATIVE_DOUBLE) > 0)
        ft = H5T_IEEE_F64LE;
    else if (H5Tequal(memtype, H5T_NATIVE_FLOAT) > 0)
        ft = H5T_IEEE_F32LE;
    else if (H5Tequal(memtype, H5T_NATIVE_INT) > 0)
        ft = H5T_STD_I32LE;
    hid_t d = H5Dcreate2(loc, name, ft, s, lcpl, dcpl, H5P_DEFAULT);
    int rc = 0;
    hssize_t np = H5Sget_simple_extent_npoints(s);
    if (d < 0 || (np > 0 && H5Dwrite(d, memtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0))
        rc = h5_fail(loc, CROM_EINTERNAL, "cannot write dataset '%s'", name);
    H5Pclose(dcpl);
    H5Pclose(lcpl);
    H5Sclose(s);
    if (d >= 0) {
        if (!rc && units)
            rc = crom_h5_set_str(d, ".", "units", units);
        if (!rc && description)
            rc = crom_h5_set_str(d, ".", "description", description);
        H5Dclose(d);
    }
    return rc;
}

int crom_h5_write(hid_t loc, const char *name, hid_t memtype, int rank,
                  const hsize_t *dims, const void *data, const char *units,
                  const char *description)
{
    const crom_schema *s = file_schema(loc);
    if (s)
        return crom_err(CROM_EINTERNAL, "dataset '%s' of a %s file: write it with crom_h5_put_*, "
                        "which take its units and description from lib/io/schema.c", name, s->schema);
    return write_dset(loc, name, memtype, rank, dims, data, units, description);
}

/* The number of dimensions of a table shape ("nv,3" has 2). */
static int shape_rank(const char *shape)
{
    int n = 1;
    for (const char *c = shape; *c; c++)
        n += *c == ',';
    return n;
}

/* The row of the table of loc's file for dataset `name` under loc, of
 * dtype `type` and `rank` dimensions; its full path goes to path. */
static int table_row(hid_t loc, const char *name, const char *type, int rank, const char *kind,
                     const crom_schema_dset **row, char *path, size_t n)
{
    const crom_schema *s = file_schema(loc);
    if (!s)
        return h5_fail(loc, CROM_EINTERNAL, "cannot write dataset '%s': not in a crom file", name);
    int rc = object_path(loc, name, path, n);
    if (rc)
        return rc;
    const crom_schema_dset *d = crom_schema_dset_find(s, path, kind);
    if (!d)
        return crom_err(CROM_EINTERNAL, "cannot write dataset /%s: %s does not list it (lib/io/schema.c)", path,
                        s->schema);
    if (strcmp(d->type, type) || shape_rank(d->shape) != rank)
        return crom_err(CROM_EINTERNAL, "cannot write dataset /%s as %s of rank %d: %s lists it as %s [%s]",
                        path, type, rank, s->schema, d->type, d->shape);
    *row = d;
    return 0;
}

static int put(hid_t loc, const char *name, hid_t memtype, const char *type, int rank,
               const hsize_t *dims, const void *data)
{
    const crom_schema_dset *d;
    char path[512];
    int rc = table_row(loc, name, type, rank, NULL, &d, path, sizeof path);
    return rc ? rc : write_dset(loc, name, memtype, rank, dims, data, d->units, d->meaning);
}

int crom_h5_put_f64(hid_t loc, const char *name, int rank, const hsize_t *dims, const double *data)
{
    return put(loc, name, H5T_NATIVE_DOUBLE, "f64", rank, dims, data);
}

int crom_h5_put_f32(hid_t loc, const char *name, int rank, const hsize_t *dims, const float *data)
{
    return put(loc, name, H5T_NATIVE_FLOAT, "f32", rank, dims, data);
}

int crom_h5_put_i32(hid_t loc, const char *name, int rank, const hsize_t *dims, const int *data)
{
    return put(loc, name, H5T_NATIVE_INT, "i32", rank, dims, data);
}

int crom_h5_write_f64(hid_t loc, const char *name, int rank, const hsize_t *dims,
                      const double *data, const char *units, const char *desc)
{
    return crom_h5_write(loc, name, H5T_NATIVE_DOUBLE, rank, dims, data, units, desc);
}

int crom_h5_write_f32(hid_t loc, const char *name, int rank, const hsize_t *dims,
                      const float *data, const char *units, const char *desc)
{
    return crom_h5_write(loc, name, H5T_NATIVE_FLOAT, rank, dims, data, units, desc);
}

int crom_h5_write_i32(hid_t loc, const char *name, int rank, const hsize_t *dims,
                      const int *data, const char *units, const char *desc)
{
    return crom_h5_write(loc, name, H5T_NATIVE_INT, rank, dims, data, units, desc);
}

int crom_h5_shape(hid_t loc, const char *name, int *rank, hsize_t *dims)
{
    if (!crom_h5_has(loc, name))
        return crom_err(CROM_EDATA, "missing dataset '%s'", name);
    hid_t d = H5Dopen2(loc, name, H5P_DEFAULT);
    if (d < 0)
        return crom_err(CROM_EDATA, "'%s' is not a dataset", name);
    hid_t s = H5Dget_space(d);
    int r = H5Sget_simple_extent_ndims(s);
    int rc = 0;
    if (r < 0 || r > CROM_IO_MAX_RANK)
        rc = crom_err(CROM_EDATA, "dataset '%s' has unsupported rank %d", name, r);
    else {
        H5Sget_simple_extent_dims(s, dims, NULL);
        *rank = r;
    }
    H5Sclose(s);
    H5Dclose(d);
    return rc;
}

int crom_h5_read(hid_t loc, const char *name, hid_t memtype, int rank,
                 hsize_t *dims, void **data)
{
    *data = NULL;
    if (!crom_h5_has(loc, name))
        return crom_err(CROM_EDATA, "missing dataset '%s'", name);
    hid_t d = H5Dopen2(loc, name, H5P_DEFAULT);
    if (d < 0)
        return crom_err(CROM_EDATA, "'%s' is not a dataset", name);
    hid_t s = H5Dget_space(d);
    hid_t ft = H5Dget_type(d);
    int r = H5Sget_simple_extent_ndims(s);
    int rc = 0;
    H5T_class_t want = H5Tget_class(memtype), have = H5Tget_class(ft);
    if (want != have)
        rc = crom_err(CROM_EDATA, "dataset '%s' has the wrong type (%s, expected %s)", name,
                      have == H5T_FLOAT ? "float" : have == H5T_INTEGER ? "integer" : "other",
                      want == H5T_FLOAT ? "float" : "integer");
    else if ((rank >= 0 && r != rank) || r > CROM_IO_MAX_RANK || r < 0)
        rc = crom_err(CROM_EDATA, "dataset '%s' has rank %d, expected %d", name, r, rank);
    if (!rc) {
        H5Sget_simple_extent_dims(s, dims, NULL);
        size_t n = 1;
        for (int i = 0; i < r; i++)
            n *= dims[i];
        size_t es = H5Tget_size(memtype);
        *data = crom_malloc(n * es);
        if (!*data)
            rc = CROM_EINTERNAL;
        else if (n && H5Dread(d, memtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, *data) < 0) {
            rc = crom_err(CROM_EDATA, "cannot read dataset '%s' (corrupt file?)", name);
            free(*data);
            *data = NULL;
        }
    }
    H5Tclose(ft);
    H5Sclose(s);
    H5Dclose(d);
    return rc;
}

int crom_h5_read_f64(hid_t loc, const char *name, int rank, hsize_t *dims, double **data)
{
    return crom_h5_read(loc, name, H5T_NATIVE_DOUBLE, rank, dims, (void **)data);
}

int crom_h5_read_f32(hid_t loc, const char *name, int rank, hsize_t *dims, float **data)
{
    return crom_h5_read(loc, name, H5T_NATIVE_FLOAT, rank, dims, (void **)data);
}

int crom_h5_read_i32(hid_t loc, const char *name, int rank, hsize_t *dims, int **data)
{
    return crom_h5_read(loc, name, H5T_NATIVE_INT, rank, dims, (void **)data);
}

/* ================================================================== inputs */

/* Read the rest of f into a buffer that starts with `head` (n0 bytes). */
static int slurp(FILE *f, const unsigned char *head, size_t n0, void **buf, size_t *len)
{
    size_t cap = 0, n = n0, hint = 1 << 20;
    struct stat st;
    if (fstat(fileno(f), &st) == 0 && S_ISREG(st.st_mode) && (size_t)st.st_size + 1 > hint)
        hint = (size_t)st.st_size + 1; /* (a regular file: one allocation) */
    unsigned char *b = NULL;
    int rc = crom_array_reserve((void **)&b, &cap, n0 > hint ? n0 : hint, 1);
    if (rc)
        return rc;
    memcpy(b, head, n0);
    for (;;) {
        if ((rc = crom_array_reserve((void **)&b, &cap, n + 1, 1))) {
            free(b);
            return crom_err_ctx("reading input");
        }
        size_t k = fread(b + n, 1, cap - n, f);
        if (k == 0)
            break;
        n += k;
    }
    if (ferror(f)) {
        free(b);
        return crom_err(CROM_EIO, "read error: %s", strerror(errno));
    }
    *buf = b;
    *len = n;
    return 0;
}

static hid_t open_image(void *buf, size_t len)
{
    return H5LTopen_file_image(buf, len,
                               H5LT_FILE_IMAGE_DONT_COPY | H5LT_FILE_IMAGE_DONT_RELEASE);
}

/* Read the field list of /frames (order from its `fields` attribute). */
static int read_fields(crom_in *in)
{
    if (!crom_h5_has(in->h5, "frames"))
        return 0;
    char *list = NULL;
    int rc = crom_h5_get_str(in->h5, "frames", "fields", &list);
    if (rc)
        return crom_err_ctx("%s: /frames", in->name);
    long nframes = -1;
    char *save = NULL;
    for (char *tok = strtok_r(list, ",", &save); tok && !rc; tok = strtok_r(NULL, ",", &save)) {
        if (in->nfields == CROM_IO_MAX_FIELDS) {
            rc = crom_err(CROM_EDATA, "%s: too many frame fields", in->name);
            break;
        }
        crom_io_field *f = &in->fields[in->nfields];
        snprintf(f->name, sizeof f->name, "%s", tok);
        char path[80];
        snprintf(path, sizeof path, "frames/%s", tok);
        hsize_t dims[CROM_IO_MAX_RANK];
        int rank;
        if ((rc = crom_h5_shape(in->h5, path, &rank, dims))) {
            crom_err_ctx("%s", in->name);
            break;
        }
        if (rank < 1) {
            rc = crom_err(CROM_EDATA, "%s: /%s has no frame dimension", in->name, path);
            break;
        }
        if (nframes < 0)
            nframes = (long)dims[0];
        else if (nframes != (long)dims[0]) {
            rc = crom_err(CROM_EDATA, "%s: /%s has %lld frames, other fields have %ld",
                          in->name, path, (long long)dims[0], nframes);
            break;
        }
        f->rank = rank - 1;
        f->count = 1;
        for (int i = 1; i < rank; i++) {
            f->dims[i - 1] = dims[i];
            f->count *= dims[i];
        }
        f->offset = in->frame_len;
        in->frame_len += f->count;
        f->dset = H5Dopen2(in->h5, path, H5P_DEFAULT);
        in->nfields++;
    }
    free(list);
    if (rc)
        return rc;
    in->nframes = nframes < 0 ? 0 : nframes;
    if (in->form == CROM_IO_STREAM || in->nframes == 0)
        return 0; /* (the buffer grows as a stream's first frame arrives) */
    /* bounded: the probe checked the frames stored back their shape */
    in->frame = crom_calloc(in->frame_len ? in->frame_len : 1, sizeof(double));
    in->frame_cap = in->frame ? (in->frame_len ? in->frame_len : 1) * sizeof(double) : 0;
    return in->frame ? 0 : CROM_EINTERNAL;
}

static int read_identity(crom_in *in);

#define COPY_MAX ((size_t)4 << 20)

/* The untrusted-input check (h5probe.h): in a child, the open and the
 * first reads crom_in_open makes, on the caller's heap layout, then a walk
 * of the whole file. in->h5 is set in the child only. */
typedef struct {
    crom_in *in;
    const char *path; /* NULL: in->image */
} replay_arg;

static hid_t replay(void *arg)
{
    replay_arg *a = arg;
    crom_in *in = a->in;
    in->h5 = a->path ? H5Fopen(a->path, H5F_ACC_RDONLY, H5P_DEFAULT)
                     : open_image(in->image, in->image_size);
    if (in->h5 >= 0 && !read_identity(in))
        read_fields(in);
    return in->h5;
}

/* The errno of the last system call that failed under HDF5, on any file. */
static int any_sys_error(void) { return sys_errno; }

static int probe(crom_in *in, const char *path)
{
    replay_arg a = {in, path};
    crom_h5probe_copy copy = {NULL, 0};
    /* an image of up to COPY_MAX bytes is replaced by the child's clean copy
     * of it (copying costs about 25 ms per MB on this machine kind: larger
     * files get the check alone) */
    crom_h5probe_src src = {replay, &a, in->image_size,
                            !path && in->image_size <= COPY_MAX ? &copy : NULL, any_sys_error};
    sys_errno = 0; /* (what the child finds is then its own) */
    sys_file[0] = 0;
    if (path) {
        struct stat st;
        if (stat(path, &st) != 0)
            return crom_err(CROM_ENOINPUT, "%s: %s", in->name, strerror(errno));
        src.len = (size_t)st.st_size;
    }
    int rc = crom_h5probe(&src, in->name);
    if (!rc && copy.buf) {
        free(in->image);
        in->image = copy.buf;
        in->image_size = copy.len;
    }
    return rc;
}

/* in->fp: the file at path, or stdin (not a terminal). */
static int open_source(crom_in *in, const char *path, int from_stdin)
{
    if (from_stdin) {
        if (isatty(0))
            return crom_err(CROM_EUSAGE, "refusing to read binary input from a terminal: "
                                         "give a file name or pipe a crom file in");
        in->fp = stdin;
        return 0;
    }
    struct stat st;
    if (stat(path, &st) != 0)
        return crom_err(CROM_ENOINPUT, "%s: %s", path, strerror(errno));
    if (S_ISDIR(st.st_mode))
        return crom_err(CROM_ENOINPUT, "%s: is a directory", path);
    in->fp = fopen(path, "rb");
    if (!in->fp)
        return crom_err(CROM_ENOINPUT, "%s: %s", path, strerror(errno));
    in->own_fp = 1;
    return 0;
}

/* An HDF5 input whose first 8 bytes, head, were read: stdin, and a file of
 * up to IMAGE_MAX bytes, are read whole into a file image, so the contained
 * check and the reads that follow see the same bytes even if the file is
 * rewritten or replaced meanwhile; a larger file is reopened by HDF5 (and
 * checked by name, which leaves that window open). */
#define IMAGE_MAX ((off_t)64 << 20)

/* IMAGE_MAX, or CROM_IO_IMAGE_MAX bytes when that is set to a number (the
 * tests use 0 to exercise the read-by-name path on small files). */
static off_t image_max(void)
{
    const char *e = getenv("CROM_IO_IMAGE_MAX");
    char *end;
    long long v = e && *e ? strtoll(e, &end, 10) : -1;
    return e && *e && !*end && v >= 0 ? (off_t)v : IMAGE_MAX;
}

static int open_h5(crom_in *in, const char *path, const unsigned char head[8], int from_stdin)
{
    in->form = CROM_IO_H5;
    struct stat st;
    if (from_stdin || (fstat(fileno(in->fp), &st) == 0 && st.st_size <= image_max())) {
        int rc = slurp(in->fp, head, 8, &in->image, &in->image_size);
        if (rc || (rc = probe(in, NULL)))
            return rc;
        in->h5 = open_image(in->image, in->image_size);
    } else {
        fclose(in->fp);
        in->fp = NULL;
        in->own_fp = 0;
        int rc = probe(in, path);
        if (rc)
            return rc;
        in->h5 = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    }
    if (in->h5 < 0)
        return crom_err(CROM_EDATA, "%s: HDF5 file is truncated or corrupt", in->name);
    return 0;
}

/* A frame stream after its magic: version and flags, the header length,
 * then the header, an HDF5 image of everything but the frames
 * (schemas/stream.md). */
static int open_stream(crom_in *in)
{
    in->form = CROM_IO_STREAM;
    uint32_t ver_flags[2];
    uint64_t hlen;
    if (read_all(in->fp, ver_flags, 8) != 8 || read_all(in->fp, &hlen, 8) != 8)
        return crom_err(CROM_EDATA, "%s: crom stream header is truncated", in->name);
    if (ver_flags[0] > STREAM_VERSION)
        return crom_err(CROM_EDATA, "%s: crom stream format v%u is newer than this crom understands (v%u)",
                        in->name, ver_flags[0], STREAM_VERSION);
    if (hlen < 8 || hlen > ((uint64_t)1 << 36))
        return crom_err(CROM_EDATA, "%s: crom stream header has an impossible length %llu", in->name,
                        (unsigned long long)hlen);
    size_t cap = 0;
    int rc = read_grown(in->fp, &in->image, &cap, (size_t)hlen, &in->image_size);
    if (rc)
        return rc;
    if (in->image_size < hlen)
        return crom_err(CROM_EDATA, "%s: crom stream header is truncated", in->name);
    rc = probe(in, NULL);
    if (rc)
        return rc;
    in->h5 = open_image(in->image, in->image_size);
    if (in->h5 < 0)
        return crom_err(CROM_EDATA, "%s: crom stream header is corrupt", in->name);
    in->complete = -1;
    return 0;
}

/* The root attributes schema and schema_version (required) and history. */
static int read_identity(crom_in *in)
{
    char *schema = NULL;
    if (crom_h5_get_str(in->h5, ".", "schema", &schema))
        return crom_err(CROM_EDATA, "%s is an HDF5 file but not a crom file (no 'schema' attribute)", in->name);
    snprintf(in->schema, sizeof in->schema, "%s", schema);
    free(schema);
    long long v;
    if (crom_h5_get_i64(in->h5, ".", "schema_version", &v))
        return crom_err(CROM_EDATA, "%s: %s file without a 'schema_version' attribute", in->name, in->schema);
    in->version = (int)v;
    if (crom_h5_has_attr(in->h5, ".", "history"))
        crom_h5_get_str(in->h5, ".", "history", &in->history);
    crom_err_clear();
    return 0;
}

/* ------------------------------------------- inputs changing under us
 * HDF5's sec2 driver reads past the end of a file as zeros, so a file cut
 * short while it is being read (an output rewritten in place, a copy still
 * in progress) would give frames of zeros. Its size and mtime at open are
 * kept, and after every frame read the descriptor HDF5 reads through is
 * checked against them (one fstat per frame). A file replaced by rename
 * is not a change: HDF5 keeps reading the version it opened. */
static long long mtime_ns(const struct stat *st)
{
    return (long long)st->st_mtim.tv_sec * 1000000000LL + st->st_mtim.tv_nsec;
}

static void watch_start(crom_in *in)
{
    in->watch_fd = -1;
    hid_t fapl = H5Fget_access_plist(in->h5);
    int sec2 = fapl >= 0 && H5Pget_driver(fapl) == H5FD_SEC2;
    if (fapl >= 0)
        H5Pclose(fapl);
    void *handle = NULL;
    struct stat st;
    if (!sec2 || H5Fget_vfd_handle(in->h5, H5P_DEFAULT, &handle) < 0 || !handle ||
        fstat(*(int *)handle, &st) != 0)
        return;
    in->watch_fd = *(int *)handle;
    in->watch_size = (long long)st.st_size;
    in->watch_mtime_ns = mtime_ns(&st);
}

static int watch_check(const crom_in *in)
{
    struct stat st;
    if (in->watch_fd < 0 || in->h5 < 0)
        return 0;
    if (fstat(in->watch_fd, &st) != 0 || (long long)st.st_size != in->watch_size ||
        mtime_ns(&st) != in->watch_mtime_ns)
        return crom_err(CROM_EDATA, "%s: changed or truncated while being read", in->name);
    return 0;
}

int crom_in_open(crom_in *in, const char *path)
{
    memset(in, 0, sizeof *in);
    in->h5 = -1;
    in->watch_fd = -1;
    in->complete = 1;
    crom_h5_quiet();
    int from_stdin = !path || !strcmp(path, "-");
    snprintf(in->name, sizeof in->name, "%s", from_stdin ? "stdin" : path);
    int rc = open_source(in, path, from_stdin);
    if (rc)
        return rc;
    unsigned char head[8];
    size_t n = read_all(in->fp, head, 8);
    if (n == 0)
        rc = crom_err(CROM_EDATA, "%s is empty (no crom file in it)", in->name);
    else if (n == 8 && !memcmp(head, hdf5_sig, 8))
        rc = open_h5(in, path, head, from_stdin);
    else if (n == 8 && !memcmp(head, STREAM_MAGIC, 8))
        rc = open_stream(in);
    else
        rc = crom_err(CROM_EDATA, "%s is not a crom file (neither HDF5 nor a crom stream)", in->name);
    if (!rc)
        rc = read_identity(in);
    if (!rc)
        rc = read_fields(in);
    if (rc) {
        crom_in_close(in);
        return rc;
    }
    if (in->form == CROM_IO_H5 && !from_stdin)
        watch_start(in);
    if (in->form == CROM_IO_STREAM) {
        in->nframes = 0;
    } else if (crom_h5_has_attr(in->h5, ".", "complete")) {
        long long c = 1;
        crom_h5_get_i64(in->h5, ".", "complete", &c);
        in->complete = c != 0;
    }
    return 0;
}

int crom_in_expect(const crom_in *in, const char *schema, int max_version)
{
    if (strcmp(in->schema, schema))
        return crom_err(CROM_EDATA, "%s is %s v%d, expected %s", in->name, in->schema,
                        in->version, schema);
    if (in->version > max_version)
        return crom_err(CROM_EDATA,
                        "%s is %s v%d, newer than this crom understands (v%d): upgrade crom",
                        in->name, in->schema, in->version, max_version);
    if (in->version < 1)
        return crom_err(CROM_EDATA, "%s: invalid schema_version %d", in->name, in->version);
    return 0;
}

int crom_in_field(const crom_in *in, const char *name)
{
    for (int i = 0; i < in->nfields; i++)
        if (!strcmp(in->fields[i].name, name))
            return i;
    crom_err(CROM_EDATA, "%s: %s has no frame field '%s'", in->name, in->schema, name);
    return -1;
}

const double *crom_in_get(const crom_in *in, int field)
{
    return in->frame + in->fields[field].offset;
}

static int read_h5_frame(crom_in *in, long k)
{
    for (int i = 0; i < in->nfields; i++) {
        crom_io_field *f = &in->fields[i];
        hsize_t start[CROM_IO_MAX_RANK + 1] = {0}, count[CROM_IO_MAX_RANK + 1];
        start[0] = (hsize_t)k;
        count[0] = 1;
        for (int j = 0; j < f->rank; j++)
            count[j + 1] = f->dims[j];
        hid_t fs = H5Dget_space(f->dset);
        H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL);
        hsize_t m = f->count;
        hid_t ms = H5Screate_simple(1, &m, NULL);
        herr_t e = H5Dread(f->dset, H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT,
                           in->frame + f->offset);
        H5Sclose(ms);
        H5Sclose(fs);
        if (e < 0)
            return watch_check(in) ? CROM_EDATA
                                   : crom_err(CROM_EDATA, "%s: cannot read frame %ld of '%s' (corrupt file?)",
                                              in->name, k, f->name);
    }
    return watch_check(in);
}

int crom_in_next(crom_in *in)
{
    if (in->form == CROM_IO_H5) {
        if (in->cursor >= in->nframes)
            return 0;
        int rc = read_h5_frame(in, in->cursor);
        if (rc)
            return rc;
        in->cursor++;
        return 1;
    }
    if (in->complete >= 0)
        return 0; /* end already seen */
    char tag[4];
    size_t n = read_all(in->fp, tag, 4);
    if (n < 4) {
        in->complete = 0; /* the writer died: no end record */
        return 0;
    }
    if (!memcmp(tag, "ENDS", 4)) {
        uint32_t status;
        uint64_t count;
        if (read_all(in->fp, &status, 4) != 4 || read_all(in->fp, &count, 8) != 8) {
            in->complete = 0;
            return 0;
        }
        if ((long)count != in->cursor)
            return crom_err(CROM_EDATA, "%s: stream end record says %llu frames, %ld were read",
                            in->name, (unsigned long long)count, in->cursor);
        in->complete = status == 0;
        return 0;
    }
    if (memcmp(tag, "FRME", 4))
        return crom_err(CROM_EDATA, "%s: corrupt crom stream after frame %ld (bad record tag)",
                        in->name, in->cursor);
    uint32_t reserved;
    uint64_t idx, bytes;
    if (read_all(in->fp, &reserved, 4) != 4 || read_all(in->fp, &idx, 8) != 8 ||
        read_all(in->fp, &bytes, 8) != 8) {
        in->complete = 0;
        return 0;
    }
    if (bytes != in->frame_len * sizeof(double))
        return crom_err(CROM_EDATA, "%s: frame %ld has %llu bytes, expected %zu", in->name,
                        in->cursor, (unsigned long long)bytes, in->frame_len * sizeof(double));
    if ((long)idx != in->cursor)
        return crom_err(CROM_EDATA, "%s: frame %llu arrived where frame %ld was expected",
                        in->name, (unsigned long long)idx, in->cursor);
    size_t got;
    int rc = read_grown(in->fp, (void **)&in->frame, &in->frame_cap, (size_t)bytes, &got);
    if (rc)
        return rc;
    if (got != bytes) {
        in->complete = 0;
        return 0;
    }
    in->cursor++;
    in->nframes = in->cursor;
    return 1;
}

int crom_in_seek(crom_in *in, long k)
{
    if (in->form == CROM_IO_STREAM) {
        if (k != in->cursor)
            return crom_err(CROM_EUSAGE, "%s: a stream can only be read forward", in->name);
        int rc = crom_in_next(in);
        return rc == 1 ? 0 : rc ? rc : crom_err(CROM_EDATA, "%s: no frame %ld", in->name, k);
    }
    if (k < 0 || k >= in->nframes)
        return crom_err(CROM_EUSAGE, "%s: no frame %ld (it has %ld)", in->name, k, in->nframes);
    int rc = read_h5_frame(in, k);
    if (!rc)
        in->cursor = k + 1;
    return rc;
}

int crom_in_read_all(crom_in *in, double **frames, long *nframes)
{
    size_t cap = 0, n = 0, fl = in->frame_len ? in->frame_len : 1;
    double *all = NULL;
    int rc = 0;
    /* (grown as frames arrive, never from the declared frame size alone) */
    while ((rc = crom_in_next(in)) == 1) {
        if ((rc = crom_array_reserve((void **)&all, &cap, n + 1, fl * sizeof(double)))) {
            free(all);
            return rc;
        }
        memcpy(all + n * fl, in->frame, in->frame_len * sizeof(double));
        n++;
    }
    if (rc) {
        free(all);
        return rc;
    }
    if (!all && !(all = crom_calloc(1, sizeof(double))))
        return CROM_EINTERNAL;
    *frames = all;
    *nframes = (long)n;
    return 0;
}

void crom_in_close(crom_in *in)
{
    for (int i = 0; i < in->nfields; i++)
        if (in->fields[i].dset > 0)
            H5Dclose(in->fields[i].dset);
    in->nfields = 0;
    if (in->h5 >= 0)
        H5Fclose(in->h5);
    in->h5 = -1;
    in->watch_fd = -1;
    if (in->own_fp && in->fp)
        fclose(in->fp);
    in->fp = NULL;
    free(in->image);
    in->image = NULL;
    free(in->frame);
    in->frame = NULL;
    free(in->history);
    in->history = NULL;
}

/* ================================================================= outputs */

/* An HDF5 file in memory for output o. HDF5 refuses to create a file under
 * the name of one it has open, even in memory, so the name is made unique
 * from o's address (no two live outputs share it); it is stored nowhere. */
static hid_t create_core(const crom_out *o)
{
    hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    H5Pset_fapl_core(fapl, 1 << 20, 0);
    char name[64];
    snprintf(name, sizeof name, "crom-image-%d-%p", (int)getpid(), (const void *)o);
    hid_t f = H5Fcreate(name, H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
    H5Pclose(fapl);
    return f;
}

static int make_tmp(crom_out *o, const char *path)
{
    char *d = crom_strdup(path), *b = crom_strdup(path);
    if (!d || !b) {
        free(d);
        free(b);
        return CROM_EINTERNAL;
    }
    const char *dir = dirname(d), *base = basename(b);
    size_t n = strlen(dir) + strlen(base) + 32;
    o->tmp = crom_malloc(n);
    if (!o->tmp) {
        free(d);
        free(b);
        return CROM_EINTERNAL;
    }
    snprintf(o->tmp, n, "%s/.%s.XXXXXX.tmp", dir, base);
    int fd = mkstemps(o->tmp, 4);
    int rc = 0;
    if (fd < 0) {
        rc = crom_err(CROM_ECANTCREAT, "cannot create %s: %s", path, strerror(errno));
        free(o->tmp);
        o->tmp = NULL;
    } else {
        /* mkstemp makes the file 0600; give it the mode a plain fopen would */
        mode_t mask = umask(0);
        umask(mask);
        if (fchmod(fd, 0666 & ~mask) != 0) {
        }
        close(fd);
        tmp_register(o->tmp, path);
    }
    free(d);
    free(b);
    return rc;
}

static void drop_tmp(crom_out *o)
{
    if (o->tmp) {
        unlink(o->tmp);
        tmp_unregister(o->tmp);
        free(o->tmp);
        o->tmp = NULL;
    }
}

int crom_fileout_open(crom_fileout *o, const char *path, int binary)
{
    memset(o, 0, sizeof *o);
    if (!path || !strcmp(path, "-")) {
        if (binary && isatty(1))
            return crom_err(CROM_EUSAGE, "refusing to write binary output to a terminal: "
                                         "use -o FILE or a pipe");
        o->f = stdout;
        o->to_stdout = 1;
        return 0;
    }
    struct stat tst;
    if (stat(path, &tst) == 0 && !S_ISREG(tst.st_mode)) { /* a device or FIFO: write in place */
        if (S_ISDIR(tst.st_mode))
            return crom_err(CROM_ECANTCREAT, "cannot create %s: is a directory", path);
        if (!(o->f = fopen(path, "wb")))
            return crom_err(CROM_ECANTCREAT, "cannot open %s: %s", path, strerror(errno));
        o->in_place = 1;
        o->target = crom_strdup(path);
        return 0;
    }
    crom_out tmp;
    memset(&tmp, 0, sizeof tmp);
    int rc = make_tmp(&tmp, path);
    if (rc)
        return rc;
    o->tmp = tmp.tmp;
    o->target = crom_strdup(path);
    o->f = fopen(o->tmp, "wb");
    if (!o->f || !o->target) {
        rc = crom_err(CROM_ECANTCREAT, "cannot create %s: %s", path, strerror(errno));
        crom_fileout_abort(o);
    }
    return rc;
}

int crom_fileout_commit(crom_fileout *o)
{
    int rc = 0;
    if (o->in_place || o->to_stdout) {
        rc = flush_close(o->f, o->in_place, o->in_place ? o->target : "stdout");
        o->f = NULL;
        free(o->target);
        o->target = NULL;
        return rc;
    }
    rc = flush_close(o->f, 1, o->target);
    o->f = NULL;
    if (!rc && rename(o->tmp, o->target) != 0)
        rc = crom_err(CROM_ECANTCREAT, "cannot create %s: %s", o->target, strerror(errno));
    if (rc)
        unlink(o->tmp);
    tmp_unregister(o->tmp);
    free(o->tmp);
    free(o->target);
    o->tmp = o->target = NULL;
    return rc;
}

void crom_fileout_abort(crom_fileout *o)
{
    if (o->f && !o->to_stdout)
        fclose(o->f);
    o->f = NULL;
    if (o->tmp) {
        unlink(o->tmp);
        tmp_unregister(o->tmp);
    }
    free(o->tmp);
    free(o->target);
    o->tmp = o->target = NULL;
}

static int write_identity(crom_out *o, const char *schema, int version,
                          const char *cmdline, const char *parent_history)
{
    char when[32];
    crom_clock_utc(when, sizeof when);
    const char *cmd = cmdline ? cmdline : "(library)";
    size_t n = (parent_history ? strlen(parent_history) : 0) + strlen(cmd) + 128;
    char *hist = crom_malloc(n);
    if (!hist)
        return CROM_EINTERNAL;
    snprintf(hist, n, "%s%s%s crom %s: %s", parent_history ? parent_history : "",
             parent_history && *parent_history ? "\n" : "", when, CROM_VERSION, cmd);
    int rc = crom_h5_set_str(o->h5, ".", "schema", schema);
    if (!rc)
        rc = crom_h5_set_i64(o->h5, ".", "schema_version", version);
    if (!rc)
        rc = crom_h5_set_str(o->h5, ".", "history", hist);
    if (!rc)
        rc = crom_h5_set_str(o->h5, ".", "crom_version", CROM_VERSION);
    free(hist);
    return rc;
}

int crom_out_create(crom_out *o, const char *path, const char *schema,
                    int version, const char *cmdline,
                    const char *parent_history, int kind)
{
    memset(o, 0, sizeof *o);
    o->h5 = -1;
    crom_h5_quiet();
    o->to_stdout = !path || !strcmp(path, "-");
    snprintf(o->name, sizeof o->name, "%s", o->to_stdout ? "stdout" : path);
    o->series = kind != CROM_OUT_PLAIN;
    if (o->to_stdout && isatty(1))
        return crom_err(CROM_EUSAGE, "refusing to write binary output to a terminal: "
                                     "use -o FILE or a pipe");
    /* a named target that exists and is not a regular file (/dev/null, a
     * FIFO) is written in place like stdout: renaming over it would replace
     * the device with a file */
    struct stat tst;
    if (!o->to_stdout && stat(path, &tst) == 0 && !S_ISREG(tst.st_mode)) {
        if (S_ISDIR(tst.st_mode))
            return crom_err(CROM_ECANTCREAT, "cannot create %s: is a directory", path);
        if (!(o->out = fopen(path, "wb")))
            return crom_err(CROM_ECANTCREAT, "cannot open %s: %s", path, strerror(errno));
        o->to_stdout = 1;
    }
    o->form = CROM_IO_H5;
    if (kind == CROM_OUT_SERIES_STREAM)
        o->form = CROM_IO_STREAM;
    else if (kind == CROM_OUT_SERIES && o->to_stdout) {
        struct stat st;
        if (fstat(1, &st) != 0 || !S_ISREG(st.st_mode))
            o->form = CROM_IO_STREAM;
    }
    int rc = 0;
    if (!o->to_stdout) {
        o->target = crom_strdup(path);
        if (!o->target || (rc = make_tmp(o, path))) {
            free(o->target);
            o->target = NULL;
            return rc ? rc : CROM_EINTERNAL;
        }
    }
    if (o->form == CROM_IO_H5 && !o->to_stdout)
        o->h5 = H5Fcreate(o->tmp, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    else
        o->h5 = create_core(o);
    if (o->h5 < 0) {
        int e = o->tmp ? sys_error_of(o->tmp) : 0;
        rc = e ? crom_err(CROM_EIO, "%s: %s", o->name, strerror(e))
               : crom_err(CROM_ECANTCREAT, "cannot create %s", o->name);
        drop_tmp(o);
        free(o->target);
        o->target = NULL;
        return rc;
    }
    if (o->form == CROM_IO_STREAM) {
        if (o->to_stdout)
            o->fp = o->out ? o->out : stdout;
        else if (!(o->fp = fopen(o->tmp, "wb"))) {
            rc = crom_err(CROM_ECANTCREAT, "cannot create %s: %s", o->name, strerror(errno));
            H5Fclose(o->h5);
            drop_tmp(o);
            free(o->target);
            o->target = NULL;
            return rc;
        }
    }
    if ((rc = write_identity(o, schema, version, cmdline, parent_history))) {
        crom_out_fail(o);
        return rc;
    }
    return 0;
}

int crom_out_field(crom_out *o, const char *name, int rank, const hsize_t *dims,
                   const char *kind)
{
    if (!o->series || o->begun)
        return crom_err(CROM_EINTERNAL, "crom_out_field('%s') on a non-series or begun output", name);
    if (o->nfields == CROM_IO_MAX_FIELDS || rank > CROM_IO_MAX_RANK - 1 ||
        strlen(name) >= sizeof o->fields[0].name)
        return crom_err(CROM_EINTERNAL, "too many or too large frame fields");
    const crom_schema_dset *row;
    char rel[sizeof o->fields[0].name + 8], path[sizeof rel];
    snprintf(rel, sizeof rel, "frames/%s", name);
    int rc = table_row(o->h5, rel, "f64", rank + 1, kind, &row, path, sizeof path);
    if (rc)
        return rc;
    crom_io_field *f = &o->fields[o->nfields];
    snprintf(f->name, sizeof f->name, "%s", name);
    f->rank = rank;
    f->count = 1;
    for (int i = 0; i < rank; i++) {
        f->dims[i] = dims[i];
        f->count *= dims[i];
    }
    f->offset = o->frame_len;
    /* dataset /frames/<name> with an unlimited frame dimension */
    hsize_t d[CROM_IO_MAX_RANK + 1], maxd[CROM_IO_MAX_RANK + 1], chunk[CROM_IO_MAX_RANK + 1];
    d[0] = 0;
    maxd[0] = H5S_UNLIMITED;
    chunk[0] = f->count >= 4096 ? 1 : 4096 / f->count;
    for (int i = 0; i < rank; i++) {
        d[i + 1] = maxd[i + 1] = dims[i];
        chunk[i + 1] = dims[i] ? dims[i] : 1;
    }
    hid_t g = crom_h5_group(o->h5, "frames");
    if (g < 0)
        return CROM_EINTERNAL;
    hid_t s = H5Screate_simple(rank + 1, d, maxd);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_obj_track_times(dcpl, 0);
    H5Pset_chunk(dcpl, rank + 1, chunk);
    f->dset = H5Dcreate2(g, name, H5T_IEEE_F64LE, s, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    H5Pclose(dcpl);
    H5Sclose(s);
    H5Gclose(g);
    if (f->dset < 0)
        return h5_fail(o->h5, CROM_EINTERNAL, "cannot create frame field '%s'", name);
    rc = crom_h5_set_str(f->dset, ".", "units", row->units);
    if (!rc)
        rc = crom_h5_set_str(f->dset, ".", "description", row->meaning);
    o->frame_len += f->count;
    o->nfields++;
    return rc;
}

static int get_image(hid_t f, void **buf, size_t *len, const char *name)
{
    H5Fflush(f, H5F_SCOPE_GLOBAL);
    ssize_t n = H5Fget_file_image(f, NULL, 0);
    if (n <= 0)
        return crom_err(CROM_EINTERNAL, "%s: cannot build the HDF5 image", name);
    *buf = crom_malloc((size_t)n);
    if (!*buf)
        return CROM_EINTERNAL;
    if (H5Fget_file_image(f, *buf, (size_t)n) != n) {
        free(*buf);
        return crom_err(CROM_EINTERNAL, "%s: cannot build the HDF5 image", name);
    }
    *len = (size_t)n;
    return 0;
}

int crom_out_begin(crom_out *o)
{
    if (o->begun)
        return 0;
    int rc = 0;
    if (o->series) {
        size_t n = 1;
        for (int i = 0; i < o->nfields; i++)
            n += strlen(o->fields[i].name) + 1;
        char *list = crom_calloc(n, 1);
        if (!list)
            return CROM_EINTERNAL;
        for (int i = 0; i < o->nfields; i++) {
            if (i)
                strcat(list, ",");
            strcat(list, o->fields[i].name);
        }
        hid_t g = crom_h5_group(o->h5, "frames");
        rc = crom_h5_set_str(g, ".", "fields", list);
        H5Gclose(g);
        free(list);
        o->pack = crom_malloc((o->frame_len ? o->frame_len : 1) * sizeof(double));
        if (!o->pack)
            return CROM_EINTERNAL;
    }
    if (!rc && o->series)
        rc = crom_h5_set_i64(o->h5, ".", "complete", 0);
    if (!rc && o->form == CROM_IO_STREAM) {
        void *img;
        size_t len;
        if ((rc = get_image(o->h5, &img, &len, o->name)))
            return rc;
        uint32_t vf[2] = {STREAM_VERSION, 0};
        uint64_t hl = len;
        rc = write_all(o->fp, STREAM_MAGIC, 8, o->name);
        if (!rc)
            rc = write_all(o->fp, vf, 8, o->name);
        if (!rc)
            rc = write_all(o->fp, &hl, 8, o->name);
        if (!rc)
            rc = write_all(o->fp, img, len, o->name);
        if (!rc)
            rc = flush_close(o->fp, 0, o->name);
        free(img);
        for (int i = 0; i < o->nfields; i++) {
            H5Dclose(o->fields[i].dset);
            o->fields[i].dset = -1;
        }
        H5Fclose(o->h5);
        o->h5 = -1;
    }
    o->begun = 1;
    return rc;
}

int crom_out_frame(crom_out *o, const double *const *vals)
{
    int rc = 0;
    if (!o->begun && (rc = crom_out_begin(o)))
        return rc;
    if (o->form == CROM_IO_STREAM) {
        for (int i = 0; i < o->nfields; i++)
            memcpy(o->pack + o->fields[i].offset, vals[i], o->fields[i].count * sizeof(double));
        uint32_t reserved = 0;
        uint64_t idx = (uint64_t)o->nframes, bytes = o->frame_len * sizeof(double);
        rc = write_all(o->fp, "FRME", 4, o->name);
        if (!rc)
            rc = write_all(o->fp, &reserved, 4, o->name);
        if (!rc)
            rc = write_all(o->fp, &idx, 8, o->name);
        if (!rc)
            rc = write_all(o->fp, &bytes, 8, o->name);
        if (!rc)
            rc = write_all(o->fp, o->pack, bytes, o->name);
        if (!rc)
            rc = flush_close(o->fp, 0, o->name);
        if (!rc)
            o->nframes++;
        return rc;
    }
    for (int i = 0; i < o->nfields && !rc; i++) {
        crom_io_field *f = &o->fields[i];
        hsize_t size[CROM_IO_MAX_RANK + 1], start[CROM_IO_MAX_RANK + 1] = {0},
                count[CROM_IO_MAX_RANK + 1];
        size[0] = (hsize_t)o->nframes + 1;
        start[0] = (hsize_t)o->nframes;
        count[0] = 1;
        for (int j = 0; j < f->rank; j++)
            size[j + 1] = count[j + 1] = f->dims[j];
        if (H5Dset_extent(f->dset, size) < 0) {
            rc = h5_fail(o->h5, CROM_EIO, "%s: cannot extend '%s'", o->name, f->name);
            break;
        }
        hid_t fs = H5Dget_space(f->dset);
        H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL);
        hsize_t m = f->count;
        hid_t ms = H5Screate_simple(1, &m, NULL);
        if (H5Dwrite(f->dset, H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT, vals[i]) < 0)
            rc = h5_fail(o->h5, CROM_EIO, "%s: cannot write frame %ld of '%s'", o->name,
                         o->nframes, f->name);
        H5Sclose(ms);
        H5Sclose(fs);
    }
    if (!rc)
        o->nframes++;
    return rc;
}

/* Close the HDF5 side and put the result in place (stdout or rename). A
 * file that cannot be flushed is left open for release() to discard. */
static int finish_h5(crom_out *o, int complete)
{
    int rc = 0;
    if (o->series)
        rc = crom_h5_set_i64(o->h5, ".", "complete", complete);
    if (!rc && o->series && !complete)
        rc = crom_h5_set_i64(o->h5, ".", "frames_written", o->nframes);
    if (rc)
        return rc;
    if (o->to_stdout) {
        void *img = NULL;
        size_t len = 0;
        FILE *f = o->out ? o->out : stdout;
        rc = get_image(o->h5, &img, &len, o->name);
        if (!rc)
            rc = write_all(f, img, len, o->name);
        if (!rc)
            rc = flush_close(f, 0, o->name);
        free(img);
        return rc;
    }
    /* everything written now (chunk caches, metadata), so that closing
     * has nothing left to write that could fail */
    if (H5Fflush(o->h5, H5F_SCOPE_LOCAL) < 0)
        return h5_fail(o->h5, CROM_EIO, "%s: cannot finish the HDF5 file", o->name);
    for (int i = 0; i < o->nfields; i++)
        if (o->fields[i].dset >= 0 && H5Dclose(o->fields[i].dset) < 0)
            h5_broken = 1;
    o->nfields = 0;
    herr_t closed = H5Fclose(o->h5);
    o->h5 = -1;
    if (closed < 0) {
        h5_broken = 1;
        return h5_fail(-1, CROM_EIO, "%s: cannot finish the HDF5 file", o->name);
    }
    if (rename(o->tmp, o->target) != 0)
        return crom_err(CROM_ECANTCREAT, "cannot create %s: %s", o->target, strerror(errno));
    tmp_unregister(o->tmp);
    free(o->tmp);
    o->tmp = NULL;
    return 0;
}

static int finish_stream(crom_out *o, int complete)
{
    int rc = 0;
    if (!o->begun)
        rc = crom_out_begin(o);
    uint32_t status = complete ? 0 : 1;
    uint64_t count = (uint64_t)o->nframes;
    if (!rc)
        rc = write_all(o->fp, "ENDS", 4, o->name);
    if (!rc)
        rc = write_all(o->fp, &status, 4, o->name);
    if (!rc)
        rc = write_all(o->fp, &count, 8, o->name);
    if (o->to_stdout) {
        int fc = flush_close(o->fp, 0, o->name);
        return rc ? rc : fc;
    }
    int fc = flush_close(o->fp, 1, o->name);
    o->fp = NULL;
    if (!rc)
        rc = fc;
    if (!rc && rename(o->tmp, o->target) != 0)
        rc = crom_err(CROM_ECANTCREAT, "cannot create %s: %s", o->target, strerror(errno));
    if (!rc) {
        tmp_unregister(o->tmp);
        free(o->tmp);
        o->tmp = NULL;
    }
    return rc;
}

/* Close every handle of o once and remove its temporary file, if any is
 * left (a failure). The file is emptied first: on a full disk HDF5's closing
 * flush then fits in the space it held, so the close succeeds and the
 * handles are really released. A close that fails anyway leaves its handle
 * to HDF5 (see h5_at_exit) and is never tried again. */
static void release(crom_out *o)
{
    if (o->tmp && o->h5 >= 0 && truncate(o->tmp, 0) != 0) {
        /* nothing more to do: the close below may then fail, handled there */
    }
    for (int i = 0; i < o->nfields; i++)
        if (o->fields[i].dset >= 0 && H5Dclose(o->fields[i].dset) < 0)
            h5_broken = 1;
    o->nfields = 0;
    if (o->h5 >= 0 && H5Fclose(o->h5) < 0)
        h5_broken = 1;
    o->h5 = -1;
    if (o->fp && o->fp != stdout && o->fp != o->out)
        fclose(o->fp);
    o->fp = NULL;
    if (o->out)
        fclose(o->out);
    o->out = NULL;
    drop_tmp(o);
    free(o->target);
    o->target = NULL;
    free(o->pack);
    o->pack = NULL;
    o->done = 1;
}

int crom_out_commit(crom_out *o)
{
    if (o->done)
        return 0;
    if (o->series && !o->begun) {
        int rc = crom_out_begin(o);
        if (rc) {
            crom_out_fail(o);
            return rc;
        }
    }
    int rc = o->form == CROM_IO_STREAM ? finish_stream(o, 1) : finish_h5(o, 1);
    release(o);
    return rc;
}

/* The errno of a system call that failed on o's file under HDF5, or 0. */
static int out_sys_error(const crom_out *o)
{
    if (o->form != CROM_IO_H5 || !o->tmp)
        return 0;
    return sys_error_of(o->tmp);
}

int crom_out_fail(crom_out *o)
{
    if (o->done)
        return 1;
    int kept = 0, sys = out_sys_error(o);
    if (o->series && o->begun && o->nframes > 0 && !sys) {
        /* keep what is finished, marked incomplete; the original error stays */
        char saved[1024];
        int code = crom_errcode();
        snprintf(saved, sizeof saved, "%s", crom_errmsg());
        int rc = o->form == CROM_IO_STREAM ? finish_stream(o, 0) : finish_h5(o, 0);
        kept = rc == 0;
        sys = kept ? 0 : out_sys_error(o);
        crom_err(code ? code : CROM_EINTERNAL, "%s", saved);
    } else if (o->form == CROM_IO_STREAM && o->begun) {
        uint32_t status = 1;
        uint64_t count = 0;
        /* a stream already started: end it as incomplete so readers know */
        if (!write_all(o->fp, "ENDS", 4, o->name) && !write_all(o->fp, &status, 4, o->name))
            write_all(o->fp, &count, 8, o->name);
        fflush(o->fp);
    }
    /* a file the system failed to write (a full disk, a device error) is
     * removed, and that is the error to report, whatever call met it first */
    if (sys)
        crom_err(CROM_EIO, "%s: %s", o->name, strerror(sys));
    release(o);
    return kept ? 0 : 1;
}

int crom_out_finish_run(crom_out *o, crom_fileout *stats, int rc)
{
    if (stats && stats->f) {
        if (rc)
            crom_fileout_abort(stats);
        else
            rc = crom_fileout_commit(stats);
    }
    if (!rc)
        return crom_out_commit(o);
    if (crom_out_fail(o) == 0)
        crom_err_ctx("%s keeps the %ld frames done, marked incomplete", o->name, o->nframes);
    return crom_errcode() == CROM_EIO ? CROM_EIO : rc;
}

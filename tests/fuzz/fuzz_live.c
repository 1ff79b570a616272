/* fuzz_live.c — crom-live's commands (lib/rom/live.c crom_live_parse): the
 * input is the text a FIFO or stdin brings, one command per line. Every
 * line parses or is refused with a message; one that parses must be a known
 * command with a terminated reference, finite numbers, a stiffness that is
 * 0 (the default) or positive, and a step count in range.
 *
 * Each line is also a page's message to crom-view (lib/view/viewer.c
 * crom_viewer_check, on a one-tet mesh with a region 'top', offering
 * "cut.h5"): what it passes on must read back as the same command with the
 * same numbers bit for bit, never step or quit, and schedule only the
 * offered path. */
#include <math.h>
#include <string.h>

#include "base/err.h"
#include "rom/live.h"
#include "view/viewer.h"

#include "fuzz.h"

static crom_mesh mesh;

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    fuzz_quiet_stdout();
    static double X[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    static int tet[4] = {0, 1, 2, 3};
    mesh.nv = 4;
    mesh.nt = 1;
    mesh.X = X;
    mesh.tets = tet;
    if (crom_mesh_region_spec(&mesh, "top=y>0.5"))
        abort();
    return 0;
}

static void viewer_check(const char *line)
{
    const char *offers[] = {"cut.h5"};
    crom_live_cmd c, back;
    char out[320];
    int rc = crom_viewer_check(&mesh, line, offers, 1, &c, out, sizeof out);
    if (rc) {
        if (rc != CROM_EUSAGE || !crom_errmsg()[0]) {
            fprintf(stderr, "viewer: '%s': code %d without a usage message\n", line, rc);
            abort();
        }
    } else if (out[0]) {
        if (crom_live_parse(out, &back) || back.kind != c.kind || strcmp(back.ref, c.ref) ||
            memcmp(back.v, c.v, sizeof c.v) || back.k != c.k || c.kind == CROM_LIVE_STEP ||
            c.kind == CROM_LIVE_QUIT || (c.kind == CROM_LIVE_SCHEDULE && strcmp(c.ref, "cut.h5"))) {
            fprintf(stderr, "viewer: '%s' passed on as '%s'\n", line, out);
            abort();
        }
    }
    crom_err_clear();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char line[512];
    size_t i = 0;
    while (i < size) {
        size_t n = 0;
        while (i < size && data[i] != '\n' && n + 1 < sizeof line)
            line[n++] = (char)data[i++];
        if (i < size && data[i] == '\n')
            i++;
        line[n] = 0;
        crom_live_cmd c;
        int rc = crom_live_parse(line, &c);
        if (rc == 0) {
            if ((int)c.kind < CROM_LIVE_NONE || c.kind > CROM_LIVE_QUIT || !memchr(c.ref, 0, sizeof c.ref) ||
                !isfinite(c.v[0]) || !isfinite(c.v[1]) || !isfinite(c.v[2]) || !(c.k == 0 || c.k > 0) ||
                (c.kind == CROM_LIVE_STEP && (c.n < 1 || c.n > 100000000L))) {
                fprintf(stderr, "bad command parsed from '%s': kind %d\n", line, (int)c.kind);
                abort();
            }
        } else if (rc != CROM_EUSAGE || !crom_errmsg()[0]) {
            fprintf(stderr, "'%s': code %d without a usage message\n", line, rc);
            abort();
        }
        crom_err_clear();
        viewer_check(line);
    }
    return 0;
}

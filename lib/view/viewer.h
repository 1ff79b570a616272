/* viewer.h — what crom-view sends a browser and what it takes from one
 * (issue 21: LiCROM's interactive application, ../shared/seeds/000_*.txt
 * Fig. 3, as a page that draws a live reduced run and drags it).
 *
 * The page decodes the surface itself: the server sends, once per mesh, the
 * surface of a cubature's mesh with each surface vertex's rest position X_v
 * and basis rows W_v (3 × r), and then per frame only the latent q (r
 * numbers), so that a frame costs 8 r bytes however fine the mesh is and the
 * page computes x_v = X_v + W_v q (the linear subspace of LiCROM eq. 1,
 * restricted to the vertices it draws).
 *
 * Messages (WebSocket binary, little-endian; a text message is a command
 * line or "error: ..."):
 *
 *   surface  "SURF" u32 index (the cubature: 0 the run's first, i the
 *            viewer's i-th offered one), u32 ns, u32 nt, u32 r, f32 lo[3], f32
 *            hi[3] (the rest bounding box), f32 X[ns][3], f32 W[ns][3][r],
 *            u32 tri[nt][3] (into the ns vertices), i32 vid[ns] (each
 *            surface vertex's index in the mesh: "#vid" names it in a
 *            command)
 *   frame    "FRAM" u32 r, u32 cubature (the index of its surface), u32 late, f64 step, f64 time, f64
 *            wall_time, f64 q[r] (from byte 40), f64 commands (the
 *            command lines the run had read before the frame's step)
 *
 * A page's command is checked here before it goes on to crom-live, so
 * that a bad one is refused with a message to the page that sent it and
 * never reaches the run. */
#ifndef CROM_VIEWER_H
#define CROM_VIEWER_H

#include <stddef.h>
#include <stdint.h>

#include "io/io.h"
#include "rom/cubature.h"
#include "rom/live.h"

typedef struct {
    int r, ns, nt;
    int *vid;       /* [ns] mesh vertex of each surface vertex */
    float *X;       /* [ns][3] rest positions (m) */
    float *W;       /* [ns][3][r] basis rows (m per unit of q) */
    uint32_t *tri;  /* [nt][3] into the ns vertices, outward oriented */
    double lo[3], hi[3];
} crom_viewer_surface;

/* The surface of c's mesh (crom_export_surface: a solid's boundary, a
 * shell's triangles) with c's basis rows. Returns 0, CROM_EUSAGE for a
 * cubature of a nonlinear map (its q is not a linear combination's
 * coefficients) or a scene, or CROM_EINTERNAL. */
int crom_viewer_surface_init(crom_viewer_surface *s, const crom_cubature *c);
void crom_viewer_surface_free(crom_viewer_surface *s);

/* Decoded positions x [ns][3] = X + W q, in doubles (what the page
 * computes in floats). */
void crom_viewer_decode(const crom_viewer_surface *s, const double *q, double *x);

/* The surface message of s as cubature `index`, after `pre` free bytes (a
 * WebSocket library's header room): *buf (malloc'ed) holds pre + *len
 * bytes. Returns 0 or CROM_EINTERNAL. */
int crom_viewer_surface_msg(const crom_viewer_surface *s, int index, size_t pre, unsigned char **buf, size_t *len);

/* The frame message into buf (48 + 8 r bytes: crom_viewer_frame_size).
 * Returns its length. */
typedef struct {
    double step, time, wall_time, commands;
    int cubature, late;
    const double *q;
} crom_viewer_frame;

size_t crom_viewer_frame_size(int r);
size_t crom_viewer_frame_msg(unsigned char *buf, int r, const crom_viewer_frame *f);

/* Check a command line from a page (crom_live_parse) against mesh m, the
 * mesh in use: REF must select vertices of m; `step` and `quit` are the
 * run's, not a page's, and refused; `schedule PATH` is allowed only for a
 * path among offered[0..noffered) (a page must not make the server open a
 * file of its choosing). On success *c is the command and out (cap bytes)
 * the line to pass on, normalized. Returns 0 or CROM_EUSAGE with a
 * message (kind NONE: nothing to pass on, returns 0 with out empty). */
int crom_viewer_check(const crom_mesh *m, const char *line, const char *const *offered, int noffered,
                      crom_live_cmd *c, char *out, size_t cap);

/* A live run's frame stream on stdin (crom-live | crom-view): a crom/latent
 * stream of model model_id (that of cubature cub, named in messages) and
 * rank r. *fq gets q's field, fld [CROM_VIEWER_NFIELDS] the fields time,
 * step, wall_time, late, cubature, commands (-1 for those absent; time must
 * be there). Returns 0 or an error with a message, in closed then. */
#define CROM_VIEWER_NFIELDS 6
int crom_viewer_stream_open(crom_in *in, const char *cub, const char *model_id, int r, int *fq, int *fld);

/* The page's greeting, a JSON object: {"cubature": PATH, "model": ID,
 * "rank": r, "vertices": nv, "offers": [PATH, ...]} (strings escaped; the
 * offers are the cubatures a page may switch to, offer i is SURF index i).
 * Returns 0 or CROM_EUSAGE when it does not fit in cap bytes. */
int crom_viewer_hello(char *buf, size_t cap, const char *cub, const char *model_id, int r, int nv,
                      const char *const *offers, int noffers);

/* Which cubature a frame is on. crom-live numbers the cubatures of a run
 * in the order it loads them (0 the first, then each 'schedule' it
 * accepts) and the stream's `cubature` field says which; a viewer knows
 * the switches it passed on, not which the run accepted. A switch passed
 * on is taken when a frame shows the next number, and dropped as refused
 * when CROM_VIEWER_SWITCH_FRAMES frames have gone by without it. */
#define CROM_VIEWER_SWITCH_FRAMES 30
#define CROM_VIEWER_SWITCHES 8
typedef struct {
    int as[64], nas;                  /* the stream's cubature k is offer as[k] (offer 0: the first) */
    int pend[CROM_VIEWER_SWITCHES], npend;
    long pend_seq[CROM_VIEWER_SWITCHES];
} crom_viewer_switches;

void crom_viewer_switches_init(crom_viewer_switches *w);
/* A switch to offer o passed on at frame seq. CROM_EUSAGE (with a
 * message) when CROM_VIEWER_SWITCHES are already under way. */
int crom_viewer_switch_passed(crom_viewer_switches *w, int o, long seq);
/* Frame seq shows the stream's cubature k: returns the offer it is (-1
 * unknown); refused [CROM_VIEWER_SWITCHES] gets the offers whose switch
 * was dropped, *nrefused how many. */
int crom_viewer_switch_frame(crom_viewer_switches *w, int k, long seq, int *refused, int *nrefused);

/* What one page drags (released for it when it goes). */
typedef struct {
    char ref[8][128];
    int n;
} crom_viewer_drags;

/* Note command c (passed on for the page): a drag adds its reference
 * (while there is room), a release removes its own or, without one, all. */
void crom_viewer_drags_note(crom_viewer_drags *d, const crom_live_cmd *c);

#endif

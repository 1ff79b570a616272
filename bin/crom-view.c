/* crom-view — a live reduced run in the browser (issue 21; LiCROM's
 * interactive application, ../shared/seeds/000_*.txt Fig. 3): reads
 * crom-live's frame stream on stdin, serves on 127.0.0.1 a page that draws
 * the body (bin/crom-view.html, WebGL 2) and decodes its surface from each
 * frame's q, and passes the page's mouse drags on to crom-live as command
 * lines (stdout or --commands FIFO), each checked first (lib/view/viewer.h).
 * HTTP and WebSocket come from libwebsockets; frames are read by a thread
 * that wakes the server's loop (lws_cancel_service). */
#include <errno.h>
#include <fcntl.h>
#include <libwebsockets.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/err.h"
#include "base/parse.h"
#include "cli/cli.h"
#include "io/io.h"
#include "rom/cubature.h"
#include "view/viewer.h"
#include "viewer_page.h" /* crom_viewer_page[]: bin/crom-view.html, made by the Makefile */

enum { O_CUB = 300, O_OFFER, O_PORT, O_CMDS };
#define MAXOFFER 16

static const crom_opt view_opts[] = {
    {"cubature", O_CUB, "CUB", "The cubature crom-live runs on (required): the surface the page draws and decodes."},
    {"offer", O_OFFER, "CUB", "Offer CUB, another cubature of the same model (a cut, punched or swapped mesh), as a button on the page that switches the run to it (crom-live's 'schedule CUB'); repeatable. A page can switch only to these and back to --cubature."},
    {"port", O_PORT, "N", "Serve on 127.0.0.1:N (default 8780; 0: a free port). Only the loopback interface listens."},
    {"commands", O_CMDS, "FILE", "Write the page's commands to FILE, a FIFO that crom-live --commands reads (default: stdout)."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Viewer options", view_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-view",
    "a live reduced run in the browser: draw it, drag it with the mouse",
    "crom-live --cubature CUB --commands FIFO ... | crom-view --cubature CUB [--port N] > FIFO",
    "Reads the frame stream of crom-live(1) on stdin and serves, on 127.0.0.1 only, a page (WebGL 2, no "
    "library) that draws the body's surface. The page gets the surface's rest positions and basis rows once "
    "and then only each frame's latent q, decoding x = X + W q itself, so a frame costs 8 r bytes whatever "
    "the mesh. Press on the body and drag: the page sends 'drag #N X,Y,Z' (N the vertex under the cursor, "
    "the point on the plane facing the eye) as the cursor moves and 'release #N' when the button comes up; "
    "drag elsewhere turns the view, the wheel zooms.\n\n"
    "Every command a page sends is checked before it goes on to crom-live (a known command with finite "
    "numbers, a region, predicate or vertex of the mesh in use; 'step' and 'quit' are the run's, and "
    "'schedule' only to an --offer'ed cubature or back to --cubature); a bad one is answered 'error: ...' on that page, logged on "
    "stderr, and never reaches the run. A page that goes away has its drags released. WebSocket "
    "connections from pages of other origins are refused.\n\n"
    "Pages report what they measure: crom-view prints, per page, the frames drawn, the median time to "
    "decode the surface, and the median time from sending a command to the frame that first shows it "
    "(the stream's commands field). The end of the stream ends crom-view; Ctrl-C asks the run to quit.",
    groups,
    "mkfifo cmds; crom-live --cubature cub.h5 --pin bottom --commands cmds | crom-view --cubature cub.h5 > cmds\n"
    "make live    # the built-in demo body, opened in a browser",
    "crom-live(1), crom-export(1)"};

typedef struct {
    const char *cub, *cmds, *offer[MAXOFFER];
    int noffer;
    long port;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    switch (key) {
    case 0: return crom_err(CROM_EUSAGE, "unexpected operand '%s' (the frames come on stdin)", v);
    case O_CUB: a->cub = v; return 0;
    case O_CMDS: a->cmds = v; return 0;
    case O_PORT: return crom_parse_int(v, "--port", 0, 65535, &a->port);
    case O_OFFER:
        if (a->noffer == MAXOFFER)
            return crom_err(CROM_EUSAGE, "--offer: at most %d cubatures", MAXOFFER);
        a->offer[a->noffer++] = v;
        return 0;
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

/* ------------------------------------------------------------ the state */

enum { ST_HELLO, ST_SURFACE, ST_FRAMES };
#define NREPLY 16

typedef struct client_s {
    struct lws *wsi;
    struct client_s *next;
    int id, stage, surf; /* surf: the offered cubature being sent / last sent */
    size_t off;          /* bytes of its surface message sent */
    long seq;            /* the last frame sent */
    char rx[4096];
    size_t rxlen;
    int rxbad;
    char reply[NREPLY][320];
    int nreply;
    crom_viewer_drags drags; /* released when the page goes */
    char stats[256];     /* the page's last report */
} client;

typedef struct {
    crom_cli *cli;
    int ncub;                      /* [0] --cubature, then --offer */
    const char *path[MAXOFFER + 1];
    crom_cubature cub[MAXOFFER + 1];
    crom_viewer_surface surf[MAXOFFER + 1];
    unsigned char *smsg[MAXOFFER + 1];
    size_t slen[MAXOFFER + 1];
    crom_viewer_switches sw;       /* which offered cubature a frame is on */
    char hello[8192];
    unsigned char *wbuf;           /* LWS_PRE + a frame or a reply: what one write sends */
    int r, fd;                     /* commands out (-1: the run no longer reads them) */
    long ncmd;                     /* command lines passed on */
    /* the reader thread's frame, under mu */
    pthread_mutex_t mu;
    crom_in in;
    int fq, fld[CROM_VIEWER_NFIELDS]; /* q, and the fields of a frame message (-1: absent) */
    double *q_in, v_in[CROM_VIEWER_NFIELDS];
    long seq_in;
    int eof, rc_in;
    char err_in[300];
    /* the main thread's copy */
    double *q, v[CROM_VIEWER_NFIELDS];
    long seq;
    int shown;                     /* offered cubature of the newest frame */
    client *clients;
    int nclient, stop, quitting;
    struct lws_context *ctx;
} server;

static volatile sig_atomic_t signalled;
static struct lws_context *signal_ctx;

static void on_signal(int sig)
{
    (void)sig;
    signalled = 1;
    if (signal_ctx)
        lws_cancel_service(signal_ctx);
}

static void lws_log(int level, const char *line)
{
    (void)level;
    fprintf(stderr, "crom-view: libwebsockets: %s", line);
}

/* One command line to the run; 0, or -1 when it no longer reads them. */
static int pass_on(server *S, const char *line)
{
    if (S->fd < 0)
        return -1;
    char b[400];
    int n = snprintf(b, sizeof b, "%s\n", line);
    for (int done = 0; done < n;) {
        ssize_t w = write(S->fd, b + done, (size_t)(n - done));
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0) {
            if (!S->quitting) /* (after Ctrl-C the run may be gone already) */
                crom_cli_warn(S->cli, "the run no longer reads commands (%s)", strerror(errno));
            S->fd = -1;
            return -1;
        }
        done += (int)w;
    }
    S->ncmd++;
    return 0;
}

static void reply(client *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void reply(client *c, const char *fmt, ...)
{
    if (c->nreply == NREPLY) /* a page that does not read: keep the newest */
        memmove(c->reply[0], c->reply[1], sizeof c->reply[0] * (NREPLY - 1)), c->nreply--;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->reply[c->nreply++], sizeof c->reply[0], fmt, ap);
    va_end(ap);
    lws_callback_on_writable(c->wsi);
}

/* A line from page c: its report, or a command checked and passed on. */
static void page_line(server *S, client *c, const char *line)
{
    if (!strncmp(line, "stats ", 6)) {
        snprintf(c->stats, sizeof c->stats, "%s", line + 6);
        for (char *p = c->stats; *p; p++) /* (a page's text on our terminal: printable only) */
            *p = *p < 0x20 || *p == 0x7f ? '?' : *p;
        if (S->cli->verbose > 1)
            crom_cli_info(S->cli, "page %d: %s", c->id, c->stats);
        return;
    }
    crom_live_cmd k;
    char out[320];
    /* (a page may switch to any of them, back to the first too) */
    int rc = crom_viewer_check(&S->cub[S->shown].mesh, line, S->path, S->ncub, &k, out, sizeof out);
    if (rc) {
        crom_cli_warn(S->cli, "page %d: %s", c->id, crom_errmsg());
        reply(c, "error: %s", crom_errmsg());
        crom_err_clear();
        return;
    }
    if (!out[0])
        return;
    int o = 0;
    while (k.kind == CROM_LIVE_SCHEDULE && strcmp(S->path[o], k.ref))
        o++;
    if (k.kind == CROM_LIVE_SCHEDULE && crom_viewer_switch_passed(&S->sw, o, S->seq)) {
        reply(c, "error: schedule %s: %s", k.ref, crom_errmsg());
        crom_err_clear();
        return;
    }
    if (pass_on(S, out)) {
        reply(c, "error: the run has ended");
        return;
    }
    if (S->cli->verbose)
        crom_cli_info(S->cli, "page %d: %s", c->id, out);
    crom_viewer_drags_note(&c->drags, &k);
    reply(c, "ok %ld", S->ncmd);
}

/* The newest frame from the reader; which offered cubature it is on. */
static void take_frame(server *S)
{
    pthread_mutex_lock(&S->mu);
    long seq = S->seq_in;
    if (seq != S->seq) {
        memcpy(S->q, S->q_in, sizeof *S->q * (size_t)S->r);
        memcpy(S->v, S->v_in, sizeof S->v);
        S->seq = seq;
    }
    if (S->eof)
        S->stop = 1;
    pthread_mutex_unlock(&S->mu);
    int refused[CROM_VIEWER_SWITCHES], nrefused;
    int o = crom_viewer_switch_frame(&S->sw, (int)S->v[4], S->seq, refused, &nrefused);
    for (int i = 0; i < nrefused; i++) /* (the run's stderr says why) */
        crom_cli_warn(S->cli, "schedule %s: the run did not switch", S->path[refused[i]]);
    S->shown = o >= 0 ? o : S->shown;
}

/* One write to page c, the most urgent first: its greeting, the surface
 * it lacks, replies, the newest frame. */
static int write_client(server *S, client *c)
{
    unsigned char *p = S->wbuf + LWS_PRE; /* (sized for a frame of rank r and a reply) */
    int more = 1, n;
    if (c->stage == ST_HELLO) {
        size_t len = strlen(S->hello);
        unsigned char *h = malloc(LWS_PRE + len);
        if (!h)
            return -1;
        memcpy(h + LWS_PRE, S->hello, len);
        n = lws_write(c->wsi, h + LWS_PRE, len, LWS_WRITE_TEXT);
        free(h);
        c->stage = ST_SURFACE;
        c->surf = S->shown;
        c->off = 0;
    } else if (c->stage == ST_SURFACE) {
        size_t chunk = 65536, left = S->slen[c->surf] - c->off, len = left < chunk ? left : chunk;
        int flags = lws_write_ws_flags(LWS_WRITE_BINARY, c->off == 0, len == left);
        unsigned char *at = S->smsg[c->surf] + LWS_PRE + c->off;
        unsigned char save[LWS_PRE];
        memcpy(save, at - LWS_PRE, LWS_PRE); /* lws writes its header in front of what it sends */
        n = lws_write(c->wsi, at, len, (enum lws_write_protocol)flags);
        memcpy(at - LWS_PRE, save, LWS_PRE);
        c->off += len;
        if (c->off == S->slen[c->surf])
            c->stage = ST_FRAMES;
    } else if (c->nreply) {
        size_t len = strlen(c->reply[0]);
        memcpy(p, c->reply[0], len);
        memmove(c->reply[0], c->reply[1], sizeof c->reply[0] * (size_t)--c->nreply);
        n = lws_write(c->wsi, p, len, LWS_WRITE_TEXT);
    } else if (c->seq != S->seq && S->seq > 0) {
        if (c->surf != S->shown) { /* the run switched meshes: that surface first */
            c->stage = ST_SURFACE;
            c->surf = S->shown;
            c->off = 0;
            lws_callback_on_writable(c->wsi);
            return 0;
        }
        /* (cubature: the surface's index, the offered cubature, as in its SURF message) */
        crom_viewer_frame f = {S->v[1], S->v[0], S->v[2], S->v[5], S->shown, (int)S->v[3], S->q};
        size_t len = crom_viewer_frame_msg(p, S->r, &f);
        c->seq = S->seq;
        n = lws_write(c->wsi, p, len, LWS_WRITE_BINARY);
    } else {
        more = 0;
        n = 0;
    }
    if (n < 0)
        return -1;
    if (more)
        lws_callback_on_writable(c->wsi);
    return 0;
}

static void page_report(server *S, const client *c)
{
    if (c->stats[0])
        crom_cli_info(S->cli, "page %d: %s", c->id, c->stats);
}

static int on_ws(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len)
{
    server *S = lws_context_user(lws_get_context(wsi));
    client *c = user;
    switch (reason) {
    case LWS_CALLBACK_FILTER_PROTOCOL_CONNECTION: { /* pages of this server only */
        char o[256] = "", a[64], b[64];
        int port = lws_get_vhost_listen_port(lws_get_vhost(wsi));
        if (lws_hdr_copy(wsi, o, sizeof o, WSI_TOKEN_ORIGIN) <= 0)
            return 0; /* not a browser */
        snprintf(a, sizeof a, "http://127.0.0.1:%d", port);
        snprintf(b, sizeof b, "http://localhost:%d", port);
        if (strcmp(o, a) && strcmp(o, b)) {
            crom_cli_warn(S->cli, "refused a WebSocket from a page of %s", o);
            return 1;
        }
        return 0;
    }
    case LWS_CALLBACK_ESTABLISHED:
        memset(c, 0, sizeof *c);
        c->wsi = wsi;
        c->id = ++S->nclient;
        c->next = S->clients;
        S->clients = c;
        if (S->cli->verbose)
            crom_cli_info(S->cli, "page %d connected", c->id);
        lws_callback_on_writable(wsi);
        return 0;
    case LWS_CALLBACK_SERVER_WRITEABLE: return write_client(S, c);
    case LWS_CALLBACK_RECEIVE:
        if (lws_frame_is_binary(wsi) || c->rxlen + len >= sizeof c->rx)
            c->rxbad = 1;
        else {
            memcpy(c->rx + c->rxlen, in, len);
            c->rxlen += len;
        }
        if (!lws_is_final_fragment(wsi))
            return 0;
        if (c->rxbad) {
            crom_cli_warn(S->cli, "page %d: a message that is not a command line (binary or over %zu bytes)", c->id,
                          sizeof c->rx - 1);
            reply(c, "error: not a command line (binary or too long)");
        } else {
            c->rx[c->rxlen] = 0;
            for (char *s = c->rx, *e; s && *s; s = e ? e + 1 : NULL) {
                if ((e = strchr(s, '\n')))
                    *e = 0;
                page_line(S, c, s);
            }
        }
        c->rxlen = 0;
        c->rxbad = 0;
        return 0;
    case LWS_CALLBACK_CLOSED:
        if (!c->wsi) /* refused before it was established */
            return 0;
        for (client **pp = &S->clients; *pp; pp = &(*pp)->next)
            if (*pp == c) {
                *pp = c->next;
                break;
            }
        for (int i = 0; i < c->drags.n; i++) { /* nobody holds what it held */
            char line[160];
            snprintf(line, sizeof line, "release %s", c->drags.ref[i]);
            pass_on(S, line);
        }
        if (S->cli->verbose || c->stats[0])
            crom_cli_info(S->cli, "page %d went away%s", c->id, c->drags.n ? " (its drags released)" : "");
        page_report(S, c);
        return 0;
    case LWS_CALLBACK_EVENT_WAIT_CANCELLED:
        if (signalled && !S->quitting) {
            S->quitting = 1;
            if (pass_on(S, "quit"))
                S->stop = 1;
        }
        take_frame(S);
        for (client *k = S->clients; k; k = k->next)
            lws_callback_on_writable(k->wsi);
        return 0;
    default: return 0;
    }
}

static int on_http(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len)
{
    size_t *sent = user;
    if (reason == LWS_CALLBACK_HTTP) {
        unsigned char h[LWS_PRE + 512], *start = h + LWS_PRE, *p = start, *end = h + sizeof h - 1;
        if (strcmp(in, "/") && strcmp(in, "/index.html"))
            return lws_return_http_status(wsi, HTTP_STATUS_NOT_FOUND, NULL) ||
                   lws_http_transaction_completed(wsi) ? -1 : 0;
        *sent = 0;
        if (lws_add_http_common_headers(wsi, HTTP_STATUS_OK, "text/html; charset=utf-8", sizeof crom_viewer_page - 1,
                                        &p, end) ||
            lws_add_http_header_by_token(wsi, WSI_TOKEN_HTTP_CACHE_CONTROL, (const unsigned char *)"no-store", 8, &p,
                                         end) ||
            lws_finalize_write_http_header(wsi, start, &p, end))
            return 1;
        lws_callback_on_writable(wsi);
        return 0;
    }
    if (reason == LWS_CALLBACK_HTTP_WRITEABLE) {
        unsigned char b[LWS_PRE + 16384];
        size_t left = sizeof crom_viewer_page - 1 - *sent, n = left < 16384 ? left : 16384;
        memcpy(b + LWS_PRE, crom_viewer_page + *sent, n);
        *sent += n;
        if (lws_write(wsi, b + LWS_PRE, n, n == left ? LWS_WRITE_HTTP_FINAL : LWS_WRITE_HTTP) != (int)n)
            return 1;
        if (n < left)
            lws_callback_on_writable(wsi);
        else if (lws_http_transaction_completed(wsi))
            return -1;
        return 0;
    }
    return lws_callback_http_dummy(wsi, reason, user, in, len);
}

static const struct lws_protocols protocols[] = {
    {"http", on_http, sizeof(size_t), 0, 0, NULL, 0},
    {"crom", on_ws, sizeof(client), 4096, 0, NULL, 0},
    {NULL, NULL, 0, 0, 0, NULL, 0}};

/* ------------------------------------------------------------ the frames */

static void *reader(void *arg)
{
    server *S = arg;
    int rc;
    while ((rc = crom_in_next(&S->in)) == 1) {
        pthread_mutex_lock(&S->mu);
        memcpy(S->q_in, crom_in_get(&S->in, S->fq), sizeof *S->q_in * (size_t)S->r);
        for (int i = 0; i < CROM_VIEWER_NFIELDS; i++)
            S->v_in[i] = S->fld[i] < 0 ? 0 : crom_in_get(&S->in, S->fld[i])[0];
        S->seq_in++;
        pthread_mutex_unlock(&S->mu);
        lws_cancel_service(S->ctx);
    }
    pthread_mutex_lock(&S->mu);
    S->eof = 1;
    S->rc_in = rc < 0 ? -rc : rc > 0 ? rc : S->in.complete == 1 ? 0 : CROM_EDATA;
    snprintf(S->err_in, sizeof S->err_in, "%s", rc ? crom_errmsg()
                                           : "the frame stream ended without its end record (did crom-live fail?)");
    pthread_mutex_unlock(&S->mu);
    lws_cancel_service(S->ctx);
    return NULL;
}

/* ------------------------------------------------------------ start and end */

static int load(server *S, const args *a)
{
    S->path[0] = a->cub;
    for (int i = 0; i < a->noffer; i++)
        S->path[i + 1] = a->offer[i];
    int rc = 0;
    for (int i = 0; !rc && i < a->noffer + 1; i++) {
        if ((rc = crom_cubature_load(S->path[i], &S->cub[i], NULL)))
            break;
        if (i && (S->cub[i].r != S->cub[0].r || strcmp(S->cub[i].model_id, S->cub[0].model_id)))
            rc = crom_err(CROM_EDATA, "--offer %s belongs to model %s (rank %d), --cubature %s to model %s (rank %d)",
                          S->path[i], S->cub[i].model_id, S->cub[i].r, a->cub, S->cub[0].model_id, S->cub[0].r);
        if (!rc && (rc = crom_viewer_surface_init(&S->surf[i], &S->cub[i])))
            crom_err(rc, "%s: %s", S->path[i], crom_errmsg());
        if (!rc)
            rc = crom_viewer_surface_msg(&S->surf[i], i, LWS_PRE, &S->smsg[i], &S->slen[i]);
        if (rc) {
            crom_viewer_surface_free(&S->surf[i]);
            crom_cubature_free(&S->cub[i]);
        } else
            S->ncub = i + 1;
    }
    if (rc)
        return rc;
    S->r = S->cub[0].r;
    crom_viewer_switches_init(&S->sw);
    return crom_viewer_hello(S->hello, sizeof S->hello, a->cub, S->cub[0].model_id, S->r, S->cub[0].mesh.nv,
                             S->path, S->ncub);
}

static int serve(server *S, const args *a)
{
    struct lws_context_creation_info info;
    memset(&info, 0, sizeof info);
    info.port = (int)a->port;
    info.iface = "127.0.0.1";
    info.options = LWS_SERVER_OPTION_DISABLE_IPV6; /* (else it binds every address, IPv6 ones too) */
    info.protocols = protocols;
    info.user = S;
    info.gid = (gid_t)-1;
    info.uid = (uid_t)-1;
    lws_set_log_level(0, NULL); /* (a failure to listen is our one line below) */
    S->ctx = lws_create_context(&info);
    if (!S->ctx)
        return crom_err(CROM_EIO, "cannot serve on 127.0.0.1:%ld (in use? try --port 0)", a->port);
    lws_set_log_level(LLL_ERR, lws_log);
    struct lws_vhost *vh = lws_get_vhost_by_name(S->ctx, "default");
    crom_cli_info(S->cli, "open http://127.0.0.1:%d/ in a browser (model %s, r = %d, %d surface vertices)",
                  vh ? lws_get_vhost_listen_port(vh) : (int)a->port, S->cub[0].model_id, S->r, S->surf[0].ns);
    pthread_t th;
    if (pthread_create(&th, NULL, reader, S)) {
        lws_context_destroy(S->ctx);
        return crom_err(CROM_EINTERNAL, "cannot start the frame reader");
    }
    signal_ctx = S->ctx;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sa.sa_flags = (int)SA_RESETHAND; /* a second Ctrl-C ends crom-view at once */
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    while (!S->stop && lws_service(S->ctx, 0) >= 0)
        ;
    for (client *c = S->clients; c; c = c->next)
        page_report(S, c);
    pthread_join(th, NULL); /* (stop comes with the stream's end, when the reader is done) */
    signal_ctx = NULL;
    S->clients = NULL;
    lws_context_destroy(S->ctx);
    int rc = S->rc_in;
    if (rc)
        crom_err(rc, "%s", S->err_in);
    else
        crom_cli_info(S->cli, "the run ended after %ld frames; %d page%s connected, %ld command lines passed on", S->seq,
                      S->nclient, S->nclient == 1 ? "" : "s", S->ncmd);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    memset(&a, 0, sizeof a);
    a.port = 8780;
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    if (!a.cub)
        return crom_cli_exit(&cli, crom_err(CROM_EUSAGE, "--cubature CUB is required (see crom-view --help)"));
    signal(SIGPIPE, SIG_IGN); /* a run that has gone: write() says EPIPE */
    server *S = calloc(1, sizeof *S);
    if (!S)
        return crom_cli_exit(&cli, CROM_EINTERNAL);
    S->cli = &cli;
    S->fd = 1;
    pthread_mutex_init(&S->mu, NULL);
    int rc = load(S, &a);
    if (!rc && a.cmds && (S->fd = open(a.cmds, O_WRONLY | O_CLOEXEC)) < 0)
        rc = crom_err(CROM_ENOINPUT, "--commands %s: %s", a.cmds, strerror(errno));
    int opened = !rc && !(rc = crom_viewer_stream_open(&S->in, S->path[0], S->cub[0].model_id, S->r, &S->fq, S->fld));
    S->q = calloc((size_t)S->r + 1, sizeof *S->q);
    S->q_in = calloc((size_t)S->r + 1, sizeof *S->q_in);
    S->wbuf = malloc(LWS_PRE + crom_viewer_frame_size(S->r) + sizeof ((client *)0)->reply[0]);
    if (!rc && (!S->q || !S->q_in || !S->wbuf))
        rc = CROM_EINTERNAL;
    if (!rc)
        rc = serve(S, &a);
    if (opened)
        crom_in_close(&S->in);
    if (S->fd > 1)
        close(S->fd);
    for (int i = 0; i < S->ncub; i++) {
        crom_cubature_free(&S->cub[i]);
        crom_viewer_surface_free(&S->surf[i]);
        free(S->smsg[i]);
    }
    free(S->q);
    free(S->q_in);
    free(S->wbuf);
    pthread_mutex_destroy(&S->mu);
    free(S);
    return crom_cli_exit(&cli, rc);
}

/* pred.c — predicates over rest positions (see pred.h). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "base/err.h"
#include "base/parse.h"
#include "mesh/pred.h"

enum { P_LT, P_GT, P_LE, P_GE, P_BOX, P_SPHERE, P_PLANE, P_ALL };

static int parse_term(const char *s, size_t len, crom_pred *p)
{
    char buf[256];
    if (len >= sizeof buf)
        return crom_err(CROM_EUSAGE, "predicate term too long");
    memcpy(buf, s, len);
    buf[len] = 0;
    if (p->nterms == CROM_PRED_MAX)
        return crom_err(CROM_EUSAGE, "predicate has more than %d terms", CROM_PRED_MAX);
    int i = p->nterms;
    char what[300];
    if (!strcmp(buf, "all")) {
        p->term[i].kind = P_ALL;
    } else if (!strncmp(buf, "box:", 4)) {
        p->term[i].kind = P_BOX;
        snprintf(what, sizeof what, "predicate '%s'", buf);
        if (crom_parse_doubles(buf + 4, what, 6, p->term[i].a))
            return CROM_EUSAGE;
        for (int k = 0; k < 3; k++)
            if (p->term[i].a[k] > p->term[i].a[k + 3])
                return crom_err(CROM_EUSAGE, "predicate '%s': box corner 1 must not exceed corner 2", buf);
    } else if (!strncmp(buf, "sphere:", 7)) {
        p->term[i].kind = P_SPHERE;
        snprintf(what, sizeof what, "predicate '%s'", buf);
        if (crom_parse_doubles(buf + 7, what, 4, p->term[i].a))
            return CROM_EUSAGE;
        if (!(p->term[i].a[3] > 0))
            return crom_err(CROM_EUSAGE, "predicate '%s': radius must be positive", buf);
    } else if (!strncmp(buf, "plane:", 6)) {
        p->term[i].kind = P_PLANE;
        snprintf(what, sizeof what, "predicate '%s'", buf);
        if (crom_parse_doubles(buf + 6, what, 4, p->term[i].a))
            return CROM_EUSAGE;
        double n = sqrt(p->term[i].a[0] * p->term[i].a[0] + p->term[i].a[1] * p->term[i].a[1] +
                        p->term[i].a[2] * p->term[i].a[2]);
        if (!(n > 0))
            return crom_err(CROM_EUSAGE, "predicate '%s': plane normal is zero", buf);
    } else if ((buf[0] == 'x' || buf[0] == 'y' || buf[0] == 'z') &&
               (buf[1] == '<' || buf[1] == '>')) {
        int axis = buf[0] - 'x';
        int ge = buf[1] == '>', eq = buf[2] == '=';
        p->term[i].kind = ge ? (eq ? P_GE : P_GT) : (eq ? P_LE : P_LT);
        p->term[i].a[0] = axis;
        snprintf(what, sizeof what, "predicate '%s'", buf);
        if (crom_parse_double(buf + 2 + eq, what, &p->term[i].a[1]))
            return CROM_EUSAGE;
    } else {
        return crom_err(CROM_EUSAGE,
                        "'%s' is not a predicate (x<V, y>=V, box:X0,Y0,Z0,X1,Y1,Z1, sphere:CX,CY,CZ,R, plane:NX,NY,NZ,D, all)",
                        buf);
    }
    p->nterms++;
    return 0;
}

int crom_pred_parse(const char *s, crom_pred *p)
{
    memset(p, 0, sizeof *p);
    if (!s || !*s)
        return crom_err(CROM_EUSAGE, "empty predicate");
    for (;;) {
        const char *e = strchr(s, '&');
        size_t len = e ? (size_t)(e - s) : strlen(s);
        int rc = parse_term(s, len, p);
        if (rc)
            return rc;
        if (!e)
            return 0;
        s = e + 1;
    }
}

int crom_pred_eval(const crom_pred *p, const double X[3])
{
    for (int i = 0; i < p->nterms; i++) {
        const double *a = p->term[i].a;
        int ok = 1;
        switch (p->term[i].kind) {
        case P_LT: ok = X[(int)a[0]] < a[1]; break;
        case P_GT: ok = X[(int)a[0]] > a[1]; break;
        case P_LE: ok = X[(int)a[0]] <= a[1]; break;
        case P_GE: ok = X[(int)a[0]] >= a[1]; break;
        case P_BOX:
            ok = X[0] >= a[0] && X[1] >= a[1] && X[2] >= a[2] && X[0] <= a[3] && X[1] <= a[4] &&
                 X[2] <= a[5];
            break;
        case P_SPHERE: {
            double dx = X[0] - a[0], dy = X[1] - a[1], dz = X[2] - a[2];
            ok = dx * dx + dy * dy + dz * dz <= a[3] * a[3];
            break;
        }
        case P_PLANE: ok = a[0] * X[0] + a[1] * X[1] + a[2] * X[2] >= a[3]; break;
        case P_ALL: ok = 1; break;
        }
        if (!ok)
            return 0;
    }
    return 1;
}

int crom_pred_is(const char *s)
{
    if (!strcmp(s, "all") || !strncmp(s, "box:", 4) || !strncmp(s, "sphere:", 7) ||
        !strncmp(s, "plane:", 6))
        return 1;
    if ((s[0] == 'x' || s[0] == 'y' || s[0] == 'z') && (s[1] == '<' || s[1] == '>'))
        return 1;
    return strchr(s, '&') != NULL;
}

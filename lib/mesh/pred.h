/* pred.h — predicates that select points by rest position: how regions are
 * written on the command line (--region top='y>0.45', --pin 'x<-0.49').
 *
 *   x<V  x>V  x<=V  x>=V (also y, z)      half-spaces
 *   box:X0,Y0,Z0,X1,Y1,Z1                  closed axis-aligned box
 *   sphere:CX,CY,CZ,R                      closed ball
 *   plane:NX,NY,NZ,D                       n·X >= D
 *   all                                    every point
 * joined by '&' for intersection ("y>0.4&x<0"). */
#ifndef CROM_PRED_H
#define CROM_PRED_H

#define CROM_PRED_MAX 8 /* terms of one predicate */

typedef struct {
    int nterms;
    struct {
        int kind;
        double a[6];
    } term[CROM_PRED_MAX];
} crom_pred;

/* Parse a predicate; returns 0 or CROM_EUSAGE naming what is wrong. */
int crom_pred_parse(const char *s, crom_pred *p);

/* 1 if X satisfies the predicate. */
int crom_pred_eval(const crom_pred *p, const double X[3]);

/* 1 if s looks like a predicate rather than a region name. */
int crom_pred_is(const char *s);

#endif

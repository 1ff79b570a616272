/* parse.h — numbers from text (base layer): each parser rejects garbage,
 * NaN and infinities with a message naming `what` (an option, a field),
 * returning CROM_EUSAGE. Used by the programs' options and the scenario.
 * Numbers are decimal only: [+-]digits[.digits][e[+-]digits]. Hexadecimal
 * (0x10), "inf", "nan", blanks and the empty string are refused, and so is
 * any magnitude beyond CROM_PARSE_MAX (no crom option means 1e308: such a
 * value only overflows later, blaming something else).
 */
#ifndef CROM_PARSE_H
#define CROM_PARSE_H

#define CROM_PARSE_MAX 1e15

int crom_parse_double(const char *s, const char *what, double *out);
/* A number in [lo, hi]; the message gives the range. */
int crom_parse_range(const char *s, const char *what, double lo, double hi, double *out);
int crom_parse_int(const char *s, const char *what, long lo, long hi, long *out);
/* Exactly n comma-separated numbers. */
int crom_parse_doubles(const char *s, const char *what, int n, double *out);
/* Between nmin and nmax comma-separated numbers; returns count in *n. */
int crom_parse_doubles_var(const char *s, const char *what, int nmin, int nmax,
                           double *out, int *n);
/* A positive, finite number. */
int crom_parse_positive(const char *s, const char *what, double *out);

#endif

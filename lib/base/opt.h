/* opt.h — the description of one command-line option (base layer): what
 * the option tables of the scenario (lib/phys/scenario.h, shared by both
 * simulators) and of the programs (lib/cli/cli.h) are made of.
 */
#ifndef CROM_OPT_H
#define CROM_OPT_H

/* One option. `key` is what the handler receives (a short letter such as 'o'
 * also makes "-o" work). `arg` is the metavariable, NULL for a flag. */
typedef struct {
    const char *name; /* long name without "--" */
    int key;          /* handler key; printable ASCII keys also act as -k */
    const char *arg;  /* metavariable ("FILE"), NULL if the option takes none */
    const char *help; /* one or more sentences */
} crom_opt;

#endif

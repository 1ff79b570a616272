/* validate.h — `crom-info --check`: an open crom input against the table of
 * its file type (schema.h). */
#ifndef CROM_VALIDATE_H
#define CROM_VALIDATE_H

#include <stdio.h>

#include "io/io.h"

/* Check an open input against its schema: every dataset and attribute is in
 * the table (none undocumented), with its dtype, shape, type and the table's
 * units (each dataset also has a description); required ones are present;
 * then the schema's own semantic checks (a mesh's tets are positively
 * oriented, frames are finite, the run is complete). Each violation is
 * printed to `report` (may be NULL) as one line; returns their number
 * (0 = valid). Reads every frame of a series. */
int crom_validate_file(crom_in *in, FILE *report);

#endif

/* image.h — RGB pictures with a depth buffer (what render.h draws into),
 * labels in a tiny bitmap font, and PNG output (libpng). */
#ifndef CROM_IMAGE_H
#define CROM_IMAGE_H

#include <stdio.h>

typedef struct {
    int w, h;
    unsigned char *rgb; /* [h][w][3] */
    float *z;           /* [h][w] depth (larger is nearer) */
} crom_image;

/* Allocate a w × h image cleared to white. Returns 0 or CROM_EINTERNAL. */
int crom_image_init(crom_image *im, int w, int h);
void crom_image_free(crom_image *im);

/* Write text (upper-case letters, digits, . , : = - + / ( ) % and space;
 * lower case is drawn as upper case) with its top-left corner at (x, y), in
 * pixel blocks of the given scale. */
void crom_image_text(crom_image *im, int x, int y, const char *s, int scale);

/* Write the image as an 8-bit RGB PNG. Returns 0 or CROM_EIO. */
int crom_image_write_png(const crom_image *im, FILE *f);

/* Write the image as PNG to path ("-": stdout, refused when a terminal),
 * atomically (crom_fileout). Returns 0, CROM_ECANTCREAT or CROM_EIO. */
int crom_image_save(const crom_image *im, const char *path);

#endif

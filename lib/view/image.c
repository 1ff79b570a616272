/* image.c — RGB images with a depth buffer, a bitmap font, PNG output
 * (image.h). */
#include <math.h>
#include <png.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "io/io.h"
#include "view/image.h"

int crom_image_init(crom_image *im, int w, int h)
{
    im->w = w;
    im->h = h;
    im->rgb = crom_malloc((size_t)w * h * 3);
    im->z = crom_malloc(sizeof(float) * (size_t)w * h);
    if (!im->rgb || !im->z) {
        crom_image_free(im);
        return CROM_EINTERNAL;
    }
    memset(im->rgb, 255, (size_t)w * h * 3);
    for (size_t i = 0; i < (size_t)w * h; i++)
        im->z[i] = -INFINITY;
    return 0;
}

void crom_image_free(crom_image *im)
{
    free(im->rgb);
    free(im->z);
    im->rgb = NULL;
    im->z = NULL;
}

/* 5×7 glyphs, one byte per row (low 5 bits, bit 4 = leftmost) */
static const struct {
    char c;
    unsigned char r[7];
} glyphs[] = {
    {'0', {14, 17, 19, 21, 25, 17, 14}}, {'1', {4, 12, 4, 4, 4, 4, 14}},
    {'2', {14, 17, 1, 2, 4, 8, 31}},     {'3', {31, 2, 4, 2, 1, 17, 14}},
    {'4', {2, 6, 10, 18, 31, 2, 2}},     {'5', {31, 16, 30, 1, 1, 17, 14}},
    {'6', {6, 8, 16, 30, 17, 17, 14}},   {'7', {31, 1, 2, 4, 8, 8, 8}},
    {'8', {14, 17, 17, 14, 17, 17, 14}}, {'9', {14, 17, 17, 15, 1, 2, 12}},
    {'A', {14, 17, 17, 31, 17, 17, 17}}, {'B', {30, 17, 17, 30, 17, 17, 30}},
    {'C', {14, 17, 16, 16, 16, 17, 14}}, {'D', {28, 18, 17, 17, 17, 18, 28}},
    {'E', {31, 16, 16, 30, 16, 16, 31}}, {'F', {31, 16, 16, 30, 16, 16, 16}},
    {'G', {14, 17, 16, 23, 17, 17, 15}}, {'H', {17, 17, 17, 31, 17, 17, 17}},
    {'I', {14, 4, 4, 4, 4, 4, 14}},      {'J', {7, 2, 2, 2, 2, 18, 12}},
    {'K', {17, 18, 20, 24, 20, 18, 17}}, {'L', {16, 16, 16, 16, 16, 16, 31}},
    {'M', {17, 27, 21, 21, 17, 17, 17}}, {'N', {17, 17, 25, 21, 19, 17, 17}},
    {'O', {14, 17, 17, 17, 17, 17, 14}}, {'P', {30, 17, 17, 30, 16, 16, 16}},
    {'Q', {14, 17, 17, 17, 21, 18, 13}}, {'R', {30, 17, 17, 30, 20, 18, 17}},
    {'S', {15, 16, 16, 14, 1, 1, 30}},   {'T', {31, 4, 4, 4, 4, 4, 4}},
    {'U', {17, 17, 17, 17, 17, 17, 14}}, {'V', {17, 17, 17, 17, 17, 10, 4}},
    {'W', {17, 17, 17, 21, 21, 21, 10}}, {'X', {17, 17, 10, 4, 10, 17, 17}},
    {'Y', {17, 17, 10, 4, 4, 4, 4}},     {'Z', {31, 1, 2, 4, 8, 16, 31}},
    {'.', {0, 0, 0, 0, 0, 12, 12}},      {',', {0, 0, 0, 0, 12, 4, 8}},
    {':', {0, 12, 12, 0, 12, 12, 0}},    {'=', {0, 0, 31, 0, 31, 0, 0}},
    {'-', {0, 0, 0, 31, 0, 0, 0}},       {'+', {0, 4, 4, 31, 4, 4, 0}},
    {'/', {1, 1, 2, 4, 8, 16, 16}},      {'(', {2, 4, 8, 8, 8, 4, 2}},
    {')', {8, 4, 2, 2, 2, 4, 8}},        {'%', {24, 25, 2, 4, 8, 19, 3}},
    {'_', {0, 0, 0, 0, 0, 0, 31}},       {' ', {0, 0, 0, 0, 0, 0, 0}}};

void crom_image_text(crom_image *im, int x, int y, const char *s, int scale)
{
    for (; *s; s++, x += 6 * scale) {
        char c = *s >= 'a' && *s <= 'z' ? (char)(*s - 32) : *s;
        const unsigned char *rows = NULL;
        for (size_t g = 0; g < sizeof glyphs / sizeof *glyphs; g++)
            if (glyphs[g].c == c)
                rows = glyphs[g].r;
        if (!rows)
            continue;
        for (int r = 0; r < 7; r++)
            for (int b = 0; b < 5; b++)
                if (rows[r] & (16 >> b))
                    for (int dy = 0; dy < scale; dy++)
                        for (int dx = 0; dx < scale; dx++) {
                            int px = x + b * scale + dx, py = y + r * scale + dy;
                            if (px >= 0 && py >= 0 && px < im->w && py < im->h)
                                memset(im->rgb + 3 * ((size_t)py * im->w + px), 20, 3);
                        }
    }
}

/* libpng's own handlers print ("libpng error: Write Error"): these only
 * return to the setjmp below, so the failure is reported once, by crom. */
static void png_quiet_error(png_structp png, png_const_charp msg)
{
    (void)msg;
    png_longjmp(png, 1);
}

static void png_quiet_warning(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

int crom_image_write_png(const crom_image *im, FILE *f)
{
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, png_quiet_error, png_quiet_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info) {
        png_destroy_write_struct(&png, &info);
        return crom_err(CROM_EINTERNAL, "cannot start a PNG");
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return ferror(f) ? crom_fileout_error(f) : crom_err(CROM_EIO, "PNG write failed");
    }
    png_init_io(png, f);
    png_set_IHDR(png, info, (png_uint_32)im->w, (png_uint_32)im->h, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int y = 0; y < im->h; y++)
        png_write_row(png, im->rgb + 3 * (size_t)y * im->w);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    return crom_fileout_error(f);
}

int crom_image_save(const crom_image *im, const char *path)
{
    crom_fileout fo;
    int rc = crom_fileout_open(&fo, path, 1);
    if (rc)
        return rc;
    if ((rc = crom_image_write_png(im, fo.f))) {
        crom_fileout_abort(&fo);
        return crom_err_ctx("%s", fo.to_stdout ? "stdout" : path);
    }
    return crom_fileout_commit(&fo);
}

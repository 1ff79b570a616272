/* test_parse.c — numbers from option text (lib/base/parse.c): decimal
 * numbers parse to their exact double; hexadecimal, inf, nan, blanks, the
 * empty string, trailing garbage and magnitudes beyond CROM_PARSE_MAX are
 * refused with CROM_EUSAGE and a message naming the option and the reason;
 * ranges and integers likewise (issue 15, defect 8). */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "base/err.h"
#include "base/parse.h"

int main(void)
{
    check_begin("test_parse");
    /* accepted: each text and its value */
    static const struct { const char *s; double v; } good[] = {
        {"0", 0}, {"-0", -0.0}, {"+1", 1}, {"1.", 1}, {".5", 0.5}, {"2.5e6", 2.5e6}, {"1E-3", 1e-3},
        {"-9.81", -9.81}, {"1e15", 1e15}, {"-1e15", -1e15}, {"0.000001", 1e-6}, {"1e-300", 1e-300}};
    for (size_t i = 0; i < sizeof good / sizeof *good; i++) {
        double v = -12345;
        int rc = crom_parse_double(good[i].s, "--x", &v);
        CHECK_MSG(rc == 0 && v == good[i].v, "'%s' gave rc %d value %.17g", good[i].s, rc, v);
    }
    /* refused: each text and a piece of its message */
    static const struct { const char *s, *why; } bad[] = {
        {"0x10", "is not a decimal number"}, {"0X1p3", "is not a decimal number"},
        {"inf", "is not a finite number"}, {"-Infinity", "is not a finite number"},
        {"nan", "is not a finite number"}, {"", "is not a number"}, {" 1", "is not a number"},
        {"1 ", "is not a number"}, {"1e", "is not a number"}, {"e5", "is not a number"}, {".", "is not a number"},
        {"1,2", "is not a number"}, {"1e308", "out of range (at most 1e+15"}, {"-2e15", "out of range"},
        {"1e400", "out of the range of a double"}, {"1e-400", "out of the range of a double"}};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        double v = 7;
        crom_err_clear();
        int rc = crom_parse_double(bad[i].s, "--x", &v);
        CHECK_MSG(rc == CROM_EUSAGE && v == 7, "'%s' gave rc %d value %g", bad[i].s, rc, v);
        CHECK_MSG(strstr(crom_errmsg(), "--x: ") == crom_errmsg() && strstr(crom_errmsg(), bad[i].why),
                  "'%s': message '%s' lacks '%s'", bad[i].s, crom_errmsg(), bad[i].why);
    }
    /* ranges: the bounds are included, and the message gives them */
    double v = 0;
    CHECK(crom_parse_range("0.5", "--r", 0.5, 2, &v) == 0 && v == 0.5);
    CHECK(crom_parse_range("2", "--r", 0.5, 2, &v) == 0 && v == 2);
    CHECK(crom_parse_range("2.0001", "--r", 0.5, 2, &v) == CROM_EUSAGE);
    CHECK_MSG(strstr(crom_errmsg(), "--r: 2.0001 is out of range [0.5, 2]") != NULL, "%s", crom_errmsg());
    CHECK(crom_parse_positive("-0", "--p", &v) == CROM_EUSAGE);
    CHECK(crom_parse_positive("1e-5", "--p", &v) == 0 && v == 1e-5);
    /* integers: decimal only, in range */
    long n = 0;
    CHECK(crom_parse_int("42", "--n", 0, 100, &n) == 0 && n == 42);
    CHECK(crom_parse_int("+7", "--n", 0, 100, &n) == 0 && n == 7);
    CHECK(crom_parse_int("-0", "--n", 0, 100, &n) == 0 && n == 0);
    static const char *badint[] = {"0x10", "1e3", "", " 1", "1.0", "inf", "nan", "12a", "-"};
    for (size_t i = 0; i < sizeof badint / sizeof *badint; i++) {
        crom_err_clear();
        CHECK_MSG(crom_parse_int(badint[i], "--n", 0, 100, &n) == CROM_EUSAGE &&
                      strstr(crom_errmsg(), "is not an integer"),
                  "'%s': %s", badint[i], crom_errmsg());
    }
    CHECK(crom_parse_int("101", "--n", 0, 100, &n) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "--n: 101 is out of range [0, 100]") != NULL);
    CHECK(crom_parse_int("99999999999999999999999", "--n", 0, 100, &n) == CROM_EUSAGE);
    CHECK(strstr(crom_errmsg(), "out of range [0, 100]") != NULL);
    /* comma lists go through the same parser */
    double g[3];
    CHECK(crom_parse_doubles("0,-9.81,0", "--gravity", 3, g) == 0 && g[1] == -9.81);
    CHECK(crom_parse_doubles("0,0x10,0", "--gravity", 3, g) == CROM_EUSAGE);
    CHECK(crom_parse_doubles("0,nan,0", "--gravity", 3, g) == CROM_EUSAGE);
    return check_done();
}

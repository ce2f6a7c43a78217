/* fitshdr.h: the card syntax of every header of a FITS file, checked before cfitsio reads it
 * (FITS standard 4.0, section 4: 80-byte cards of printable ASCII, a keyword of A-Z 0-9 - _, and
 * after "= " a quoted string, a logical, an integer, a real, a complex or nothing, then an
 * optional comment). Internal to export/. */
#ifndef IPSD_EXPORT_FITSHDR_H
#define IPSD_EXPORT_FITSHDR_H

#include <stddef.h>

#include "base/err.h"

/* Walks the HDUs of the len bytes at buf (each header to its END card, then past its data, as
 * BITPIX, NAXISn, PCOUNT and GCOUNT size them) and checks every card of every header. 0, or
 * -EINVAL with the HDU, card and rule that failed. The walk stops without error at data cut by
 * the file's end or at a block that does not begin another extension (what follows is then
 * cfitsio's to judge: it reads no header there). */
int fitshdr_check(const unsigned char *buf, size_t len, err_t *err);

#endif

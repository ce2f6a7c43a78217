/* stage_url.h (internal to instrument/): the stage string of --stage and stage_open_url, parsed
 * into its parts (stage.h documents the syntax). Pure text handling: no I/O. Every controller
 * family has the same form, FAMILY:tcp://HOST:PORT or FAMILY:serial:/dev/DEVICE with options;
 * the link and timing options are common, a few are the family's own. */
#ifndef IPSD_INSTRUMENT_STAGE_URL_H
#define IPSD_INSTRUMENT_STAGE_URL_H

#include "base/err.h"

enum { STAGE_URL_SIM, STAGE_URL_GCS, STAGE_URL_ZABER };
enum { STAGE_LINK_TCP, STAGE_LINK_SERIAL };

#define STAGE_URL_AXES 3
#define STAGE_URL_AXIS_LEN 9 /* GCS axis identifiers are at most 8 characters */

typedef struct stage_url {
    int backend;                                   /* STAGE_URL_SIM, _GCS or _ZABER */
    int link;                                      /* STAGE_LINK_TCP or STAGE_LINK_SERIAL */
    char host[256];                                /* TCP: host name or address */
    int port;                                      /* TCP: 1..65535 */
    char device[256];                              /* serial: the device path */
    int baud;                                      /* serial: 115200 */
    double unit_um;                                /* micrometres per controller unit (GCS 1000:
                                                      mm; Zaber: step_um=, the microstep) */
    char axes[STAGE_URL_AXES][STAGE_URL_AXIS_LEN]; /* GCS identifiers of x, y, z ("1", "2", "3");
                                                      Zaber: axis numbers 1..9 */
    int devices[STAGE_URL_AXES];                   /* Zaber: device numbers of x, y, z (1) */
    int n_axes;                                    /* 2 (no z: z stays 0) or 3 */
    double timeout_s;                              /* a reply must arrive within (5 s) */
    double move_timeout_s;                         /* a move or referencing within (60 s) */
    int poll_ms;                                   /* pause between ONT? polls (10 ms) */
    int reference;                                 /* reference unreferenced axes (GCS FRF,
                                                      Zaber home) at opening (1) */
} stage_url_t;

/* Parses text. Returns 0 or -EINVAL with err saying what is wrong (no flag name: the caller
 * adds it). */
int stage_url_parse(const char *text, stage_url_t *u, err_t *err);

#endif

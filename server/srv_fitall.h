/* srv_fitall.h: the fit job of every pixel a scan covers (srv_fitall.c), run by a fit worker. */
#ifndef IPSD_SERVER_SRV_FITALL_H
#define IPSD_SERVER_SRV_FITALL_H

#include "server/srv_params.h"
#include "srv_int.h"

/* Fits and stores the covered pixels of job's scan from pixel job->points_done on; the last
 * pixel's transaction ends the job as done. Returns 0 (done), -ECANCELED (stopped: cancelled or
 * the shutdown; the pixels stored stay) or an error (the job should fail). */
int srv_fitall_run(srv_worker_t *w, storage_job_t *job, const srv_fit_params_t *p, err_t *err);

#endif

/* ipsd.c: the ipsd daemon: the server core (server/srv_main.c) with the HTTP API as its front
 * end. Usage: ipsd --help. */
#include "api/api.h"

int main(int argc, char **argv)
{
    return srv_main(argc, argv, &api_frontend);
}

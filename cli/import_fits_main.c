/* import_fits_main.c: main of ips-import-fits, the program behind `ips import-fits`
 * (cmd_import_fits.c). A separate executable so that ips itself does not link cfitsio (and the
 * libcurl it brings): see cli/CMakeLists.txt and export_exec.c. */
#include "commands.h"

int main(int argc, char **argv)
{
    return cmd_import_fits(argc, argv);
}

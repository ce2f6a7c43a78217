/* export_main.c: main of ips-export, the program behind `ips export` (cmd_export.c). It is a
 * separate executable so that ips itself does not link cfitsio (and the libcurl it brings): see
 * cli/CMakeLists.txt and export_exec.c. */
#include "commands.h"

int main(int argc, char **argv)
{
    return cmd_export(argc, argv);
}

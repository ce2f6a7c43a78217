# embed.cmake: writes the file IN as a C byte array (api_openapi_json, NUL-terminated, and its
# length api_openapi_json_len) into OUT. Run by cmake -P at build time.
file(READ ${IN} hex HEX)
string(LENGTH "${hex}" n)
math(EXPR n "${n} / 2")
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${hex}")
string(REGEX REPLACE "((0x[0-9a-f][0-9a-f],){16})" "\\1\n" bytes "${bytes}")
file(WRITE ${OUT} "/* generated from ${IN} by api/embed.cmake: do not edit */\n"
    "#include <stddef.h>\n"
    "static const unsigned char data[] = {\n${bytes}0x00};\n"
    "const char *const api_openapi_json = (const char *)data;\n"
    "const size_t api_openapi_json_len = ${n};\n")

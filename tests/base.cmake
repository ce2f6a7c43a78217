# Tests of base/ (libipsbase).
ipsd_add_test(test_utf8 ipsbase)

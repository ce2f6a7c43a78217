# Tests of base/ (libipsbase).
ipsd_add_test(test_utf8 ipsbase)
ipsd_add_test(test_g17 ipsbase m)

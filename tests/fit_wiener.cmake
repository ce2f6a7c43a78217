# Tests of fit/wiener.c (the Wiener baseline) and fit/interp.c (display interpolation).
ipsd_add_test(test_wiener ipsfit PkgConfig::JANSSON)
ipsd_add_test(test_interp ipsfit)

# Tests of fit/ (libipsfit) owned by the fit core.
ipsd_add_test(test_airy ipsfit PkgConfig::JANSSON)
ipsd_add_test(test_box ipsfit PkgConfig::JANSSON)
ipsd_add_test(test_design ipsfit)
ipsd_add_test(test_model ipsfit PkgConfig::JANSSON)
ipsd_add_test(test_pipeline ipsfit PkgConfig::JANSSON)

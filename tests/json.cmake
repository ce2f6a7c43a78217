# Tests of json/ (libipsjson).
ipsd_add_test(test_jdump ipsjson m)

$node_(0) set X_ 10.0
$node_(0) set Y_ 10.0
$node_(1) set X_ 200.0
$node_(1) set Y_ 200.0
$ns_ at 1.0 "$node_(0) setdest 110.0 10.0 10.0"
$ns_ at 5.0 "$node_(0) set Y_ 50.0"
$ns_ at 3.0 "$node_(1) set X_ 250.0 "
$ns_ at 6.0 "$node_(1) setdest 250.0 300.0 20.0"
$ns_ at 8.0 "$node_(1) set Y_ 100.0"
$ns_ at 20.0 "$node_(0) setdest 10.0 10.0 5.0"

$node_(0) set X_ 1.5
$node_(0) set Y_ 2.5
$node_(1) set X_ 50.25
$node_(1) set Y_ 60.75
$ns_ at 0.0 "$node_(0) setdest 11.5 2.5 1.0"
$ns_ at 0.0 "$node_(1) setdest 80.0 60.75 2.5"
$ns_ at 10.0 "$node_(0) setdest 11.5 42.5 4.0"
$ns_ at 11.9 "$node_(1) setdest 80.0 10.0 2.5"

# a comment line
$node_(0) set X_ 10.0
$node_(0) set Y_ 20.0
$node_(0) set Z_ 0.0
$node_(1) set X_ 100.0
$node_(1) set Y_ 100.0
$god_ set-dist 0 1 2
$ns_ at 1.0 "$node_(0) setdest 50.0 20.0 5.0"
$ns_ at 3.0 "$node_(0) setdest 50.0 60.0 10.0"
$ns_ at 2.0 "$node_(1) set X_ 150.0"
$ns_ at 30.0 "$god_ set-dist 0 1 7"
set god_ [God instance]
$ns_ at 4.0 "$node_(1) setdest 150.0 200.0 10.0"   ;# trailing comment

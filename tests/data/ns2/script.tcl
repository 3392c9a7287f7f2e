# A whole simulation script with the movement lines inside it, as ns-2 users write them.
set val(chan)   Channel/WirelessChannel ;# channel type
set val(nn)     3                       ;# number of mobilenodes
set ns_ [new Simulator]
set tracefd [open simple.tr w]
$ns_ trace-all $tracefd
set topo [new Topography]
$topo load_flatgrid 500 500
create-god $val(nn)
for {set i 0} {$i < $val(nn) } {incr i} {
    set node_($i) [$ns_ node]
    $node_($i) random-motion 0 ;# disable random motion
}
$node_(0) set X_ 5.0
$node_(0) set Y_ 2.0
$node_(0) set Z_ 0.0
$node_(1) set X_ 390.0
$node_(1) set Y_ 385.0
$node_(1) set Z_ 0.0
$node_(2) set X_ 100.0
$node_(2) set Y_ 100.0
$ns_ at 5.0 "$node_(1) setdest 25.0 20.0 15.0"
$ns_ at 2.0 "$node_(0) setdest 20.0 18.0 1.0"
$ns_ at 10.0 "$node_(2) setdest 200.0 100.0 5.0  "
$ns_ at 12.0 "$node_(2) setdest 200.0 100.0 5.0"
$ns_ at abc "$node_(2) setdest 0.0 0.0 5.0"
$ns_ at -3.0 "$node_(2) setdest 0.0 0.0 5.0"
$ns_ at 20.0 "$node_(0) setdest 20.0 18.0 3.0"
for {set i 0} {$i < $val(nn) } {incr i} {
    $ns_ at 150.0 "$node_($i) reset";
}
$ns_ at 150.0001 "stop"
proc stop {} {
    global ns_ tracefd
    close $tracefd
}
puts "Starting Simulation..."
$ns_ run

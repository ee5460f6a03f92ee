"""Output stage: pose records into packets with CRC, the UART, the PS FIFO, and the pose
link that wires them."""

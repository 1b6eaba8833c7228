#define STEPS 4
#define LEN 0.5

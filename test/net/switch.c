/*
 * switch.c - a small user-space Ethernet switch with per-port impairments, for network tests.
 *
 *     switch [-s SEED] IFNAME...
 *
 * Runs in a network namespace that holds one end of each host's veth pair (IFNAME: one
 * port each). It reads every frame arriving on a port with an AF_PACKET socket bound to
 * that interface (frames it sent itself, PACKET_OUTGOING, are skipped), learns source MAC
 * addresses, and forwards each frame to the port that owns its destination MAC, or floods
 * it to every other port (broadcast, multicast, unknown unicast).
 *
 * Impairments are per port, that is per host link, and apply in both directions: on the
 * frames a host sends (ingress, at the switch) and on the frames sent to it (egress). A
 * frame from host A to host B therefore meets A's impairments, then B's:
 *
 *   cut     the link is down: every frame from or to the port is dropped (frames already
 *           queued for the port are dropped when due).
 *   loss P  each frame is dropped with probability P, drawn once per frame per impaired
 *           link crossed: once on ingress (for all of its copies) and once per egress copy.
 *           A to B: delivered with probability (1 - P_A)(1 - P_B). Every IP fragment is a
 *           frame of its own.
 *   delay D, jitter J (ms)
 *           each frame waits D + U(-J, +J) ms (uniform, never below 0), drawn once per
 *           frame per link: A to B waits the sum of A's and B's draws. Draws are
 *           independent, so with jitter frames can be REORDERED (as with netem). With
 *           "fifo=1" on a port, frames from or to it are never reordered: each also waits
 *           for the frame queued before it for the same egress port (so delays are then
 *           no longer uniform, and a frame from another host to that egress port may wait
 *           behind it too, as on one real link).
 *
 * Control: one command per line on stdin; each is answered on stdout by zero or more data
 * lines and then "ok" or "error: ...". PORT is an interface name or a port index.
 *
 *   set PORT [delay=MS] [jitter=MS] [loss=P] [fifo=0|1]
 *   cut PORT 0|1
 *   stats          one line per port: NAME rx= tx= lost= cut= err= kdrop= csum= queued=
 *   quit
 *
 * "ready" is printed once every port is open. The switch exits on "quit", at the end of
 * stdin (its parent is gone), or at SIGTERM/SIGINT; SIGUSR1 writes the counters to stderr.
 *
 * Counters per port: rx frames received from the host, tx frames delivered to it, lost
 * and cut frames dropped by this port's loss or cut (either direction), err frames that
 * could not be sent or queued, kdrop frames the kernel dropped before the switch read
 * them (socket buffer full), csum checksums completed, queued frames waiting for it.
 *
 * Checksums: a frame a host sends on a veth usually carries a partial UDP/TCP checksum
 * (CHECKSUM_PARTIAL: only the pseudo-header sum, the device is to finish it). AF_PACKET
 * flags it TP_STATUS_CSUMNOTREADY in PACKET_AUXDATA; forwarded as it is, the receiver
 * would drop it as corrupt. The switch computes the full checksum of such IPv4/IPv6
 * UDP/TCP frames before forwarding. Frames larger than the egress MTU (TCP segmentation
 * offload) cannot be sent and count as err: the hosts' interfaces must not make them
 * ("ip link set eth0 gso_max_segs 1").
 * VLAN tags are not kept.
 */
#define _GNU_SOURCE
#include <arpa/inet.h>
#include <errno.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define MAX_PORTS 64
#define MAX_MACS 1024
#define FRAME_MAX (65536 + 1024)
#define QUEUE_MAX_BYTES (64u << 20) /* frames held for their delay, beyond which they are dropped (err) */
#define RX_BATCH 256                /* frames read from one port before the others get a turn */
#define RCVBUF (8 << 20)

struct counters {
	uint64_t rx, tx, lost, cut, err, kdrop, csum, queued;
};

struct port {
	char name[IF_NAMESIZE];
	int fd;
	double delay_ms, jitter_ms, loss;
	int cut, fifo;
	uint64_t last_due; /* due time of the latest frame queued for it (fifo) */
	struct counters c;
};

struct frame { /* a frame waiting for its delay */
	uint64_t due, seq;
	int port;
	size_t len;
	unsigned char *data;
};

static struct port ports[MAX_PORTS];
static int nports;
static struct {
	unsigned char mac[6];
	int port;
} macs[MAX_MACS];
static int nmacs;
static struct frame *heap;
static size_t heap_len, heap_cap, queued_bytes;
static uint64_t seq_counter, rng_state;
static volatile sig_atomic_t got_stop, got_usr1;

static uint64_t now_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static double uniform(void) /* [0, 1), splitmix64 */
{
	uint64_t z = (rng_state += 0x9e3779b97f4a7c15u);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9u;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebu;
	return (double)((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
}

static int dropped(double p)
{
	return p > 0.0 && uniform() < p;
}

static uint64_t draw_delay_ns(const struct port *p)
{
	double ms = p->delay_ms;
	if (p->jitter_ms > 0.0)
		ms += p->jitter_ms * (2.0 * uniform() - 1.0);
	return ms > 0.0 ? (uint64_t)(ms * 1e6) : 0;
}

/* ------------------------------------------------------------------ timer queue (min-heap on due, seq) */

static int earlier(const struct frame *a, const struct frame *b)
{
	return a->due < b->due || (a->due == b->due && a->seq < b->seq);
}

static void swap(size_t i, size_t j)
{
	struct frame t = heap[i];
	heap[i] = heap[j];
	heap[j] = t;
}

static int heap_push(struct frame f)
{
	if (heap_len == heap_cap) {
		size_t cap = heap_cap ? 2 * heap_cap : 1024;
		struct frame *h = realloc(heap, cap * sizeof *h);
		if (!h)
			return -1;
		heap = h;
		heap_cap = cap;
	}
	size_t i = heap_len++;
	heap[i] = f;
	while (i > 0 && earlier(&heap[i], &heap[(i - 1) / 2])) {
		swap(i, (i - 1) / 2);
		i = (i - 1) / 2;
	}
	return 0;
}

static struct frame heap_pop(void)
{
	struct frame top = heap[0];
	heap[0] = heap[--heap_len];
	for (size_t i = 0;;) {
		size_t l = 2 * i + 1, r = l + 1, m = i;
		if (l < heap_len && earlier(&heap[l], &heap[m]))
			m = l;
		if (r < heap_len && earlier(&heap[r], &heap[m]))
			m = r;
		if (m == i)
			break;
		swap(i, m);
		i = m;
	}
	return top;
}

/* ------------------------------------------------------------------ checksums */

static uint64_t sum16(const unsigned char *p, size_t n, uint64_t s)
{
	for (; n > 1; p += 2, n -= 2)
		s += (uint64_t)(p[0] << 8 | p[1]);
	if (n)
		s += (uint64_t)p[0] << 8;
	return s;
}

/* Complete the UDP/TCP checksum of an IPv4/IPv6 frame whose checksum is partial; 1 if done. */
static int complete_checksum(unsigned char *f, size_t len)
{
	const unsigned char *ip = f + ETH_HLEN;
	size_t l4, l4len;
	unsigned proto;
	uint64_t s;
	if (len < ETH_HLEN + 20u)
		return 0;
	unsigned type = (unsigned)(f[12] << 8 | f[13]);
	if (type == ETHERTYPE_IP && (ip[0] >> 4) == 4) {
		size_t ihl = (size_t)(ip[0] & 15) * 4, total = (size_t)(ip[2] << 8 | ip[3]);
		if (ihl < 20 || total < ihl || ETH_HLEN + total > len || ((ip[6] << 8 | ip[7]) & 0x3fff))
			return 0; /* malformed, or a fragment (offset or more-fragments set) */
		proto = ip[9];
		l4 = ETH_HLEN + ihl;
		l4len = total - ihl;
		s = sum16(ip + 12, 8, 0);
	} else if (type == ETHERTYPE_IPV6 && (ip[0] >> 4) == 6) {
		if (len < ETH_HLEN + 40u)
			return 0;
		proto = ip[6]; /* no extension headers */
		l4 = ETH_HLEN + 40;
		l4len = (size_t)(ip[4] << 8 | ip[5]);
		if (l4 + l4len > len)
			return 0;
		s = sum16(ip + 8, 32, 0);
	} else {
		return 0;
	}
	size_t at = proto == IPPROTO_UDP ? 6 : proto == IPPROTO_TCP ? 16 : 0;
	if (!at || l4len < at + 2)
		return 0;
	f[l4 + at] = f[l4 + at + 1] = 0;
	s = sum16(f + l4, l4len, s + proto + l4len);
	while (s >> 16)
		s = (s & 0xffff) + (s >> 16);
	uint16_t c = (uint16_t)~s;
	if (c == 0 && proto == IPPROTO_UDP)
		c = 0xffff;
	f[l4 + at] = (unsigned char)(c >> 8);
	f[l4 + at + 1] = (unsigned char)c;
	return 1;
}

/* ------------------------------------------------------------------ forwarding */

static void learn(const unsigned char *mac, int port)
{
	if (mac[0] & 1)
		return; /* a group address is never a source */
	for (int i = 0; i < nmacs; i++)
		if (!memcmp(macs[i].mac, mac, 6)) {
			macs[i].port = port;
			return;
		}
	int i = nmacs < MAX_MACS ? nmacs++ : (int)(seq_counter % MAX_MACS);
	memcpy(macs[i].mac, mac, 6);
	macs[i].port = port;
}

static int lookup(const unsigned char *mac)
{
	if (mac[0] & 1)
		return -1;
	for (int i = 0; i < nmacs; i++)
		if (!memcmp(macs[i].mac, mac, 6))
			return macs[i].port;
	return -1;
}

static void transmit(int out, const unsigned char *data, size_t len)
{
	struct port *p = &ports[out];
	if (p->cut)
		p->c.cut++;
	else if (send(p->fd, data, len, MSG_DONTWAIT) == (ssize_t)len)
		p->c.tx++;
	else
		p->c.err++;
}

/* Whether a frame through port ``p`` goes nowhere: the port is cut, or the frame is lost (counted). */
static int blocked(struct port *p)
{
	if (p->cut) {
		p->c.cut++;
		return 1;
	}
	if (dropped(p->loss)) {
		p->c.lost++;
		return 1;
	}
	return 0;
}

/* One copy of a frame to port ``out``: its egress impairments, then now or later (after the
 * frame queued before it for ``out`` if ``in_order``). */
static void forward(int out, const unsigned char *data, size_t len, uint64_t now, uint64_t delay, int in_order)
{
	struct port *p = &ports[out];
	if (blocked(p))
		return;
	uint64_t due = now + delay + draw_delay_ns(p);
	if ((in_order || p->fifo) && due < p->last_due)
		due = p->last_due;
	p->last_due = due;
	if (due <= now) {
		transmit(out, data, len);
		return;
	}
	struct frame f = {due, seq_counter++, out, len, NULL};
	if (queued_bytes + len > QUEUE_MAX_BYTES || !(f.data = malloc(len))) {
		p->c.err++;
		return;
	}
	memcpy(f.data, data, len);
	if (heap_push(f) < 0) {
		free(f.data);
		p->c.err++;
		return;
	}
	queued_bytes += len;
	p->c.queued++;
}

static void on_frame(int in, unsigned char *data, size_t len, unsigned status)
{
	struct port *p = &ports[in];
	p->c.rx++;
	if (len < ETH_HLEN)
		return;
	if (blocked(p))
		return;
	if ((status & TP_STATUS_CSUMNOTREADY) && complete_checksum(data, len))
		p->c.csum++;
	learn(data + 6, in);
	int dst = lookup(data);
	uint64_t now = now_ns(), delay = draw_delay_ns(p);
	for (int out = 0; out < nports; out++)
		if (out != in && (dst < 0 || out == dst))
			forward(out, data, len, now, delay, p->fifo);
}

static void send_due(void)
{
	uint64_t now = now_ns();
	while (heap_len && heap[0].due <= now) {
		struct frame f = heap_pop();
		ports[f.port].c.queued--;
		queued_bytes -= f.len;
		transmit(f.port, f.data, f.len);
		free(f.data);
	}
}

static void read_port(int in)
{
	static unsigned char buf[FRAME_MAX];
	union {
		struct cmsghdr h;
		char space[CMSG_SPACE(sizeof(struct tpacket_auxdata))];
	} ctl;
	for (int n = 0; n < RX_BATCH; n++) {
		struct sockaddr_ll from;
		struct iovec iov = {buf, sizeof buf};
		struct msghdr msg = {.msg_name = &from, .msg_namelen = sizeof from, .msg_iov = &iov, .msg_iovlen = 1};
		msg.msg_control = ctl.space;
		msg.msg_controllen = sizeof ctl.space;
		ssize_t len = recvmsg(ports[in].fd, &msg, MSG_DONTWAIT);
		if (len < 0)
			return;
		if (from.sll_pkttype == PACKET_OUTGOING)
			continue;
		if (msg.msg_flags & MSG_TRUNC) {
			ports[in].c.rx++;
			ports[in].c.err++;
			continue;
		}
		unsigned status = 0;
		for (struct cmsghdr *c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c))
			if (c->cmsg_level == SOL_PACKET && c->cmsg_type == PACKET_AUXDATA) {
				struct tpacket_auxdata aux;
				memcpy(&aux, CMSG_DATA(c), sizeof aux);
				status = aux.tp_status;
			}
		on_frame(in, buf, (size_t)len, status);
	}
}

/* ------------------------------------------------------------------ ports, control */

static int open_port(struct port *p, const char *name)
{
	unsigned ifindex = if_nametoindex(name);
	if (!ifindex || strlen(name) >= sizeof p->name) {
		fprintf(stderr, "switch: no interface %s\n", name);
		return -1;
	}
	strcpy(p->name, name);
	p->fd = socket(AF_PACKET, SOCK_RAW, htons(ETH_P_ALL));
	struct sockaddr_ll sll = {.sll_family = AF_PACKET, .sll_protocol = htons(ETH_P_ALL), .sll_ifindex = (int)ifindex};
	struct packet_mreq promisc = {.mr_ifindex = (int)ifindex, .mr_type = PACKET_MR_PROMISC};
	int one = 1, rcvbuf = RCVBUF;
	if (p->fd < 0 || bind(p->fd, (struct sockaddr *)&sll, sizeof sll) < 0 ||
	    setsockopt(p->fd, SOL_PACKET, PACKET_AUXDATA, &one, sizeof one) < 0 ||
	    setsockopt(p->fd, SOL_PACKET, PACKET_ADD_MEMBERSHIP, &promisc, sizeof promisc) < 0) {
		fprintf(stderr, "switch: port %s: %s\n", name, strerror(errno));
		return -1;
	}
	setsockopt(p->fd, SOL_PACKET, PACKET_IGNORE_OUTGOING, &one, sizeof one); /* Linux >= 4.20; else skipped */
	if (setsockopt(p->fd, SOL_SOCKET, SO_RCVBUFFORCE, &rcvbuf, sizeof rcvbuf) < 0)
		setsockopt(p->fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
	return 0;
}

static void print_counters(FILE *out)
{
	for (int i = 0; i < nports; i++) {
		struct port *p = &ports[i];
		struct tpacket_stats st;
		socklen_t n = sizeof st;
		if (!getsockopt(p->fd, SOL_PACKET, PACKET_STATISTICS, &st, &n)) /* and resets them */
			p->c.kdrop += st.tp_drops;
		fprintf(out,
			"%s rx=%llu tx=%llu lost=%llu cut=%llu err=%llu kdrop=%llu csum=%llu queued=%llu\n",
			p->name, (unsigned long long)p->c.rx, (unsigned long long)p->c.tx,
			(unsigned long long)p->c.lost, (unsigned long long)p->c.cut, (unsigned long long)p->c.err,
			(unsigned long long)p->c.kdrop, (unsigned long long)p->c.csum,
			(unsigned long long)p->c.queued);
	}
}

static struct port *find_port(const char *word)
{
	char *end;
	long i = word ? strtol(word, &end, 10) : -1;
	if (word && *word && !*end)
		return i >= 0 && i < nports ? &ports[i] : NULL;
	for (int k = 0; word && k < nports; k++)
		if (!strcmp(ports[k].name, word))
			return &ports[k];
	return NULL;
}

/* "key=value" with value a number in [lo, hi] into *out; 1 if it matched key, -1 if bad. */
static int option(const char *word, const char *key, double lo, double hi, double *out)
{
	size_t n = strlen(key);
	if (strncmp(word, key, n) || word[n] != '=')
		return 0;
	char *end;
	double v = strtod(word + n + 1, &end);
	if (end == word + n + 1 || *end || !(v >= lo && v <= hi))
		return -1;
	*out = v;
	return 1;
}

static const char *cmd_set(struct port *p, char **save)
{
	double delay = p->delay_ms, jitter = p->jitter_ms, loss = p->loss, fifo = p->fifo;
	for (char *w; (w = strtok_r(NULL, " \t", save));) {
		int r = option(w, "delay", 0, 600000, &delay);
		r = r ? r : option(w, "jitter", 0, 600000, &jitter);
		r = r ? r : option(w, "loss", 0, 1, &loss);
		r = r ? r : option(w, "fifo", 0, 1, &fifo);
		if (r <= 0)
			return "bad option (delay=MS jitter=MS loss=P fifo=0|1)";
	}
	p->delay_ms = delay;
	p->jitter_ms = jitter;
	p->loss = loss;
	p->fifo = fifo != 0.0;
	return NULL;
}

/* Run one command line; 1 to quit. */
static int command(char *line)
{
	char *save;
	const char *verb = strtok_r(line, " \t\r", &save), *err = NULL;
	if (!verb)
		return 0;
	if (!strcmp(verb, "quit")) {
		printf("ok\n");
		return 1;
	} else if (!strcmp(verb, "stats")) {
		print_counters(stdout);
	} else if (!strcmp(verb, "set") || !strcmp(verb, "cut")) {
		struct port *p = find_port(strtok_r(NULL, " \t\r", &save));
		const char *arg = p && verb[0] == 'c' ? strtok_r(NULL, " \t\r", &save) : NULL;
		if (!p)
			err = "no such port";
		else if (verb[0] == 's')
			err = cmd_set(p, &save);
		else if (arg && (!strcmp(arg, "0") || !strcmp(arg, "1")))
			p->cut = arg[0] == '1';
		else
			err = "cut PORT 0|1";
	} else {
		err = "unknown command (set, cut, stats, quit)";
	}
	if (err)
		printf("error: %s\n", err);
	else
		printf("ok\n");
	return 0;
}

/* Read what stdin has and run each complete line; 1 to quit (or end of input). */
static int read_commands(void)
{
	static char buf[4096];
	static size_t have;
	ssize_t n = read(STDIN_FILENO, buf + have, sizeof buf - 1 - have);
	if (n <= 0)
		return n < 0 && errno == EINTR ? 0 : 1;
	have += (size_t)n;
	buf[have] = '\0';
	char *start = buf, *nl;
	int quit = 0;
	while (!quit && (nl = strchr(start, '\n'))) {
		*nl = '\0';
		quit = command(start);
		start = nl + 1;
	}
	fflush(stdout);
	have -= (size_t)(start - buf);
	memmove(buf, start, have);
	if (have == sizeof buf - 1) /* a line longer than the buffer */
		have = 0;
	return quit;
}

static void on_signal(int sig)
{
	if (sig == SIGUSR1)
		got_usr1 = 1;
	else
		got_stop = 1;
}

int main(int argc, char **argv)
{
	int opt;
	rng_state = 1;
	while ((opt = getopt(argc, argv, "s:")) != -1) {
		if (opt != 's')
			goto usage;
		rng_state = strtoull(optarg, NULL, 0);
	}
	nports = argc - optind;
	if (nports < 1 || nports > MAX_PORTS)
		goto usage;
	for (int i = 0; i < nports; i++)
		if (open_port(&ports[i], argv[optind + i]) < 0)
			return 1;

	sigset_t block, none;
	sigemptyset(&block);
	sigemptyset(&none);
	int sigs[] = {SIGTERM, SIGINT, SIGHUP, SIGUSR1};
	struct sigaction sa = {.sa_handler = on_signal};
	for (size_t i = 0; i < sizeof sigs / sizeof *sigs; i++) {
		sigaddset(&block, sigs[i]);
		sigaction(sigs[i], &sa, NULL);
	}
	sigprocmask(SIG_BLOCK, &block, NULL); /* delivered only inside ppoll: no lost wake-up */
	signal(SIGPIPE, SIG_IGN);

	struct pollfd fds[MAX_PORTS + 1];
	for (int i = 0; i < nports; i++)
		fds[i] = (struct pollfd){.fd = ports[i].fd, .events = POLLIN};
	fds[nports] = (struct pollfd){.fd = STDIN_FILENO, .events = POLLIN};
	printf("ready\n");
	fflush(stdout);

	while (!got_stop) {
		send_due();
		struct timespec wait, *timeout = NULL;
		if (heap_len) {
			uint64_t now = now_ns(), left = heap[0].due > now ? heap[0].due - now : 0;
			wait = (struct timespec){(time_t)(left / 1000000000u), (long)(left % 1000000000u)};
			timeout = &wait;
		}
		int ready = ppoll(fds, (nfds_t)nports + 1, timeout, &none);
		if (got_usr1) {
			got_usr1 = 0;
			print_counters(stderr);
		}
		if (ready <= 0)
			continue;
		for (int i = 0; i < nports; i++)
			if (fds[i].revents & POLLIN)
				read_port(i);
		if (fds[nports].revents && read_commands())
			break;
	}
	print_counters(stderr);
	return 0;
usage:
	fprintf(stderr, "usage: switch [-s SEED] IFNAME... (at most %d)\n", MAX_PORTS);
	return 2;
}

// SPDX-License-Identifier: GPL-2.0
/*
 * vig_gpio_sim: a simulated GPIO chip with edge interrupts, driven from debugfs.
 *
 * Debian's kernels build neither gpio-sim nor gpio-mockup (nor the irq_sim they rely on), so
 * the device tests bring this small chip instead. It registers one gpiochip (label
 * "vig-gpio-sim", `lines` inputs) whose input levels are set by writing "OFFSET LEVEL" to
 * /sys/kernel/debug/vig-gpio-sim/pull; a level change raises the line's interrupt (from an
 * irq_work, so in hard-interrupt context as a real controller's would be) when its trigger
 * type asks for that edge, and gpiolib's character device turns it into a timestamped edge
 * event. A write returns once its interrupt has been handled, so each edge raises an interrupt
 * of its own (gpiolib's threaded handler may still merge edges that come faster than it
 * runs). Reading `pull` gives the levels as a string of 0 and 1.
 */
#include <linux/bitmap.h>
#include <linux/debugfs.h>
#include <linux/gpio/driver.h>
#include <linux/interrupt.h>
#include <linux/irq.h>
#include <linux/irq_work.h>
#include <linux/module.h>
#include <linux/mutex.h>
#include <linux/platform_device.h>
#include <linux/slab.h>
#include <linux/uaccess.h>

#define VSIM_MAX_LINES 64

static unsigned int lines = 8;
module_param(lines, uint, 0444);
MODULE_PARM_DESC(lines, "number of lines (1..64)");

struct vsim {
	struct gpio_chip gc;
	struct platform_device *pdev;
	struct dentry *dir;
	struct irq_work work;
	struct mutex lock; /* serialises writers of `level` */
	DECLARE_BITMAP(level, VSIM_MAX_LINES);
	DECLARE_BITMAP(enabled, VSIM_MAX_LINES);
	DECLARE_BITMAP(pending, VSIM_MAX_LINES);
	unsigned int type[VSIM_MAX_LINES];
};

static struct vsim *sim;

static int vsim_get(struct gpio_chip *gc, unsigned int offset)
{
	struct vsim *s = gpiochip_get_data(gc);

	return test_bit(offset, s->level);
}

static int vsim_get_direction(struct gpio_chip *gc, unsigned int offset)
{
	return GPIO_LINE_DIRECTION_IN;
}

static int vsim_direction_input(struct gpio_chip *gc, unsigned int offset)
{
	return 0;
}

static void vsim_irq_mask(struct irq_data *d)
{
	struct gpio_chip *gc = irq_data_get_irq_chip_data(d);
	struct vsim *s = gpiochip_get_data(gc);
	irq_hw_number_t hw = irqd_to_hwirq(d);

	clear_bit(hw, s->enabled);
	gpiochip_disable_irq(gc, hw);
}

static void vsim_irq_unmask(struct irq_data *d)
{
	struct gpio_chip *gc = irq_data_get_irq_chip_data(d);
	struct vsim *s = gpiochip_get_data(gc);
	irq_hw_number_t hw = irqd_to_hwirq(d);

	gpiochip_enable_irq(gc, hw);
	set_bit(hw, s->enabled);
}

static int vsim_irq_set_type(struct irq_data *d, unsigned int type)
{
	struct gpio_chip *gc = irq_data_get_irq_chip_data(d);
	struct vsim *s = gpiochip_get_data(gc);

	if (type & ~IRQ_TYPE_EDGE_BOTH)
		return -EINVAL; /* edges only: no level interrupts */
	WRITE_ONCE(s->type[irqd_to_hwirq(d)], type);
	return 0;
}

static const struct irq_chip vsim_irqchip = {
	.name = "vig-gpio-sim",
	.irq_mask = vsim_irq_mask,
	.irq_unmask = vsim_irq_unmask,
	.irq_set_type = vsim_irq_set_type,
	.flags = IRQCHIP_IMMUTABLE | IRQCHIP_SKIP_SET_WAKE,
	GPIOCHIP_IRQ_RESOURCE_HELPERS,
};

/* Hard-interrupt context: hand each pending line to its interrupt handler. */
static void vsim_irq_work(struct irq_work *work)
{
	struct vsim *s = container_of(work, struct vsim, work);
	unsigned int offset;

	for_each_set_bit(offset, s->pending, s->gc.ngpio) {
		if (test_and_clear_bit(offset, s->pending))
			generic_handle_domain_irq(s->gc.irq.domain, offset);
	}
}

static ssize_t vsim_pull_write(struct file *file, const char __user *ubuf, size_t count,
			       loff_t *ppos)
{
	char buf[32];
	unsigned int offset, value;
	bool old;
	unsigned int type;

	if (count == 0 || count >= sizeof(buf))
		return -EINVAL;
	if (copy_from_user(buf, ubuf, count))
		return -EFAULT;
	buf[count] = '\0';
	if (sscanf(buf, "%u %u", &offset, &value) != 2 || offset >= sim->gc.ngpio || value > 1)
		return -EINVAL;
	mutex_lock(&sim->lock);
	old = test_bit(offset, sim->level);
	assign_bit(offset, sim->level, value);
	type = READ_ONCE(sim->type[offset]);
	if (old != value && test_bit(offset, sim->enabled) &&
	    (type & (value ? IRQ_TYPE_EDGE_RISING : IRQ_TYPE_EDGE_FALLING))) {
		set_bit(offset, sim->pending);
		irq_work_queue(&sim->work);
		/* One interrupt per edge: the write waits until this one has been handled. */
		irq_work_sync(&sim->work);
	}
	mutex_unlock(&sim->lock);
	return count;
}

static ssize_t vsim_pull_read(struct file *file, char __user *ubuf, size_t count, loff_t *ppos)
{
	char buf[VSIM_MAX_LINES + 2];
	unsigned int i;

	for (i = 0; i < sim->gc.ngpio; i++)
		buf[i] = test_bit(i, sim->level) ? '1' : '0';
	buf[i++] = '\n';
	return simple_read_from_buffer(ubuf, count, ppos, buf, i);
}

static const struct file_operations vsim_pull_fops = {
	.owner = THIS_MODULE,
	.open = simple_open,
	.read = vsim_pull_read,
	.write = vsim_pull_write,
	.llseek = default_llseek,
};

static int __init vsim_init(void)
{
	struct gpio_irq_chip *girq;
	int rc;

	if (lines < 1 || lines > VSIM_MAX_LINES)
		return -EINVAL;
	sim = kzalloc(sizeof(*sim), GFP_KERNEL);
	if (!sim)
		return -ENOMEM;
	mutex_init(&sim->lock);
	init_irq_work(&sim->work, vsim_irq_work);
	sim->pdev = platform_device_register_simple("vig-gpio-sim", PLATFORM_DEVID_NONE, NULL, 0);
	if (IS_ERR(sim->pdev)) {
		rc = PTR_ERR(sim->pdev);
		goto free;
	}
	sim->gc.label = "vig-gpio-sim";
	sim->gc.parent = &sim->pdev->dev;
	sim->gc.owner = THIS_MODULE;
	sim->gc.base = -1;
	sim->gc.ngpio = lines;
	sim->gc.can_sleep = false;
	sim->gc.get = vsim_get;
	sim->gc.get_direction = vsim_get_direction;
	sim->gc.direction_input = vsim_direction_input;
	girq = &sim->gc.irq;
	gpio_irq_chip_set_chip(girq, &vsim_irqchip);
	girq->handler = handle_simple_irq;
	girq->default_type = IRQ_TYPE_NONE;
	girq->num_parents = 0;
	girq->parents = NULL;
	girq->parent_handler = NULL;
	rc = gpiochip_add_data(&sim->gc, sim);
	if (rc)
		goto unregister;
	sim->dir = debugfs_create_dir("vig-gpio-sim", NULL);
	debugfs_create_file("pull", 0600, sim->dir, NULL, &vsim_pull_fops);
	return 0;

unregister:
	platform_device_unregister(sim->pdev);
free:
	kfree(sim);
	return rc;
}

static void __exit vsim_exit(void)
{
	debugfs_remove_recursive(sim->dir);
	gpiochip_remove(&sim->gc);
	irq_work_sync(&sim->work);
	platform_device_unregister(sim->pdev);
	kfree(sim);
}

module_init(vsim_init);
module_exit(vsim_exit);
MODULE_DESCRIPTION("Simulated GPIO chip with edge interrupts, driven from debugfs");
MODULE_LICENSE("GPL");

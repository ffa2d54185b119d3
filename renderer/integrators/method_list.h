/* method_list.h: every render method, one row each: RD_METHOD(id) names the `const rd_method
 * rd_method_<id>` that the method's own file defines (integrators/<file>.c). The rows are
 * expanded twice, into the declarations (rd_method.h) and into the table (methods.c), so adding
 * a method is its file and one row here. The table lists the methods in this order. No include
 * guard: it is meant to be included once per expansion. */
RD_METHOD(delta)
RD_METHOD(guided)
RD_METHOD(guided_unbiased)
RD_METHOD(transmittance)
RD_METHOD(uniform)

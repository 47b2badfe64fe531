#include "bk.h"
#include <cstdio>
int main(){ for(int trial=0;trial<20;++trial){ int n=30,m=16; Eigen::MatrixXd A=Eigen::MatrixXd::Random(n,n); A=A+A.transpose().eval();
 for(int i=0;i<n;++i)for(int j=0;j<=i;++j) if((i*7+j*3+trial)%5<3 && i!=j){A(i,j)=0;A(j,i)=0;}
 for(int i=0;i<n;i+=2)A(i,i)=0;
 Eigen::MatrixXd K=A; PartialBK bk; bk.factor(K,m); bk.Kp=&K; int n2=0; for(int k=0;k<m;++k) n2+=bk.piv2[k];
 Eigen::VectorXd y0=Eigen::VectorXd::Random(n), yr=A.fullPivLu().solve(y0), yy=y0; bk.forward(yy);
 Eigen::MatrixXd Sc=K.bottomRightCorner(n-m,n-m).selfadjointView<Eigen::Lower>(); double e1=(yy.tail(n-m)-Sc*yr.tail(n-m)).norm(); yy.tail(n-m)=yr.tail(n-m); bk.backward(yy);
 printf("2x2 %d fwd %g back %g\n",n2,e1,(yy-yr).norm());}}
